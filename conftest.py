"""Every property test draws the same examples on every run: a suite that passes on a clean
clone passes again in CI, and a failure there is a failure here (hypothesis' derandomize)."""
from hypothesis import settings

settings.register_profile("deterministic", derandomize=True, database=None)
settings.load_profile("deterministic")
