"""What the hot-reload tests share: a filter file whose version shows in its estimate, and a
write that moves the modification time on (file systems with coarse timestamps)."""

from __future__ import annotations

import os
import textwrap

# A filter whose estimate is the initial mean shifted by OFFSET metres in x: the offset
# tells which version of the file built it. ``steps`` counts predictions since reset.
SOURCE = textwrap.dedent("""
    import numpy as np
    from beacon_sim.filters.base import FilterBase

    OFFSET = {offset}

    class Shift(FilterBase):
        def reset(self, initial):
            self.mean = np.array(initial.mean, dtype=float)
            self.cov = np.array(initial.cov, dtype=float)
            self.steps = 0

        def predict(self, control, dt):
            self.steps += 1

        def update(self, measurements):
            pass

        def estimate(self):
            m = self.mean.copy()
            m[0] += OFFSET
            return m, self.cov.copy()
""")


def write(path, text, bump_s):
    """Write and set the modification time ``bump_s`` seconds later than now (file systems
    with coarse timestamps would otherwise see no change within one second)."""
    path.write_text(text)
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + int(bump_s * 1e9)))
