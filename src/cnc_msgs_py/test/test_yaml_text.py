"""Jobs, plants and work offsets are read by libyaml's C loader where PyYAML has it, and
read exactly as the pure-Python safe loader reads them."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from cnc_msgs_py.yaml_text import LOADER, load_yaml

CONFIG = Path(__file__).resolve().parents[3] / "config"
FILES = sorted(CONFIG.rglob("*.yaml"))


def test_the_c_loader_is_used_where_pyyaml_has_it():
    assert LOADER is (yaml.CSafeLoader if yaml.__with_libyaml__ else yaml.SafeLoader)


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(CONFIG)))
def test_every_config_file_reads_as_the_safe_loader_reads_it(path):
    text = path.read_text()
    assert load_yaml(text) == yaml.safe_load(text)


def test_what_the_safe_loader_refuses_is_refused():
    with pytest.raises(yaml.YAMLError):
        load_yaml("!!python/object/apply:os.system ['true']")
    with pytest.raises(yaml.YAMLError):
        load_yaml("a: [1, 2")
