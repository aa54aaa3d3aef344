"""Files: the recording format, export to arrays, the UTIAS MRCLAM reader. No simulation
here (replaying a file is beacon_sim/runs/replay.py)."""
