"""Seeing models and runs in MuJoCo's viewer (``docs/viewing.md``).

MuJoCo Studio (shipped with MuJoCo 4) serves a browser viewer; it runs in a child
process (:mod:`.child`, driven by :mod:`.studio`, its web server behind our guard by
:mod:`.studio_guard`), so what it prints and how it fails
stay out of the command that uses it. :mod:`.watch` reconverts a description when a
file it read changes (``urdf2mjcf view``); :mod:`.live` shows a run while it runs
(``facility-demo --view``, ``rover-drive --view``).
"""
