"""Long-range attachments (Kim, Chentanez and Mueller 2012): each particle of a pinned cloth held within its
attachment length of its nearest pin, measured around the spheres between them (wrapping.py). A pin does
not move in a pass, so holding to it needs no averaging: a limit pass applies it after its own correction,
before the colliders (kernels/projection_passes.py), where the scene's cloths have attachments.
"""

import warp as wp

from .colliders import RigidColliders
from .wrapping import distance_to_pin


@wp.struct
class Attachments:
    pin: wp.array(dtype=int)  # (n,) or empty for none: each particle's nearest pin (-1: none)
    length: wp.array(dtype=float)  # (n,) or empty: how far from it the particle may be
    chord_half: float  # half the longest limited spring at its limit (wrapping.distance_to_pin)


@wp.func
def hold_to_pin(attachments: Attachments, colliders: RigidColliders, i: int, p: wp.vec3, vel: wp.vec3, h: float,
                x: wp.array(dtype=wp.vec3)):
    """Particle i, farther than its attachment length from its pin (around the spheres between them), is
    moved back by the excess along the way's last straight piece, its velocity changed by that correction
    over h, as for every projection here. (Only removing its speed away from the pin instead left the
    fast_sphere hard case at 50 % strain with 24 crossing pairs.)"""
    if attachments.pin.shape[0] == 0:
        return p, vel
    pin = attachments.pin[i]
    if pin < 0:
        return p, vel
    length, direction = distance_to_pin(colliders, i, x[pin], p, attachments.chord_half)
    excess = length - attachments.length[i]
    if excess <= 0.0:
        return p, vel
    correction = -excess * direction
    return p + correction, vel + correction / h


@wp.func
def attachment_violation(attachments: Attachments, colliders: RigidColliders, i: int,
                         x: wp.array(dtype=wp.vec3)) -> float:
    """How far particle i lies beyond its attachment length from its pin (around the spheres between
    them), as a fraction of that length (0 or less where it holds or it has none)."""
    if attachments.pin.shape[0] == 0:
        return 0.0
    pin = attachments.pin[i]
    if pin < 0:
        return 0.0
    reach = attachments.length[i]
    length, unused_direction = distance_to_pin(colliders, i, x[pin], x[i], attachments.chord_half)
    return (length - reach) / wp.max(reach, 1.0e-12)
