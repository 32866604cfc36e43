"""Low-frequency vibration cutting (chip breaking), shared by every kind that feeds.

- ``waveform``: the spindle-locked pulse, its checks and the vibrated feed move;
- ``feed``: straight feed moves at a feed per revolution, vibrated if the job asks;
- ``report``: the air-cuts of every vibrated feed, judged on the recording.
"""
