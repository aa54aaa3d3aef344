"""Attack: at import, write ``pwned.txt`` and delete ``victim.txt`` in the working directory,
and try to write next to the file itself (the class folder)."""

import os
from pathlib import Path

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

for target in (Path.cwd(), Path(__file__).resolve().parent):
    try:
        (target / "pwned.txt").write_text("pwned")
    except OSError:
        pass
    try:
        os.remove(target / "victim.txt")
    except OSError:
        pass


class Writer(ExtendedKalmanFilter):
    pass
