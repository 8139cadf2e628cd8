"""The thickness surface contacts hold, in metres: one value for both kinds, edge to edge
(kernels/edge_collision.py) and vertex to triangle (face_contacts.py). The device model asks ``thickness``
once (``ParticleContacts.thickness``) and both kinds take it from there.

A scene's ``[collision] thickness`` sets it in metres, a thickness that does not follow the mesh (issue 34).
Without it, edge contacts alone (``edges = true``, seed_default's) hold ``RULE`` contact distances
(``Collision.separation`` times the largest particle radius)."""

from __future__ import annotations

from .scene import Collision

RULE = 0.25  # contact distances: below the midpoints' gap across the tightest fold the particles allow


def thickness(settings: Collision, max_radius: float) -> float:
    """How far apart edge and face contacts hold surfaces, metres: the scene's ``thickness`` where it sets
    one, else ``RULE`` of the contact distance ``separation`` x ``max_radius``."""
    return settings.thickness if settings.thickness is not None else RULE * settings.separation * max_radius
