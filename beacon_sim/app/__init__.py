"""The pygame front end: the window, its drawing and its keys (the only place pygame is imported)."""

import os

# No "Hello from the pygame community" banner on every start.
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
