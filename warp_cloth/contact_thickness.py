"""The thickness surface contacts hold, in metres: one value for both kinds, edge to edge (a scene's
``edges = true``, kernels/edge_collision.py) and vertex to triangle (the lab's face contacts,
face_contacts.py). The device model asks ``thickness`` once (``ParticleContacts.thickness``) and both kinds
take it from there.

Its default is the edge contacts' rule, ``RULE`` contact distances (``Collision.separation`` times the largest
particle radius), which is what a scene's edge contacts hold (seed_default's among them). The lab sets it in
metres with ``lab_hooks``, a thickness that does not follow the mesh (issue 34); no scene key yet."""

from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator

RULE = 0.25  # contact distances: below the midpoints' gap across the tightest fold the particles allow

# The lab's hook, not a scene key: simulators built while it is set hold both kinds at it (metres).
LAB_THICKNESS: float | None = None


@contextmanager
def lab_hooks(thickness: float | None = None) -> Iterator[None]:
    """Simulators built inside hold both contact kinds ``thickness`` metres apart (None: the rule)."""
    global LAB_THICKNESS
    if thickness is not None and not thickness > 0.0:
        raise ValueError(f"surface contacts need a thickness above 0, got {thickness}")
    before = LAB_THICKNESS
    LAB_THICKNESS = thickness
    try:
        yield
    finally:
        LAB_THICKNESS = before


def thickness(separation: float, max_radius: float) -> float:
    """How far apart edge and face contacts hold surfaces, metres: the lab's where it sets one, else ``RULE``
    of the contact distance ``separation`` x ``max_radius``."""
    return LAB_THICKNESS if LAB_THICKNESS is not None else RULE * separation * max_radius
