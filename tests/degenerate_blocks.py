"""Blocks whose adjustment cannot determine everything, shared by the tests of the messages
that name what is undetermined."""

from dataclasses import replace

import numpy as np

from baarda.block.photo_block import Block, Cameras
from baarda.simulate.aerial import FlightPlan, simulate_block


def flat_strip_camera_per_photo() -> Block:
    """A flat strip of three nadir photos in a free network, each with a camera of its own
    whose c, x0 and y0 are free: X0 and x0 of a photo cannot be told apart."""
    b, _ = simulate_block(FlightPlan(strips=1, photos_per_strip=3, pattern=3, control="none",
                                     height_chains=0, relief_m=0.0, seed=2))
    n, c = len(b.photos), b.cameras
    cams = Cameras([f"cam{p}" for p in b.photos.ids], np.repeat(c.focal_mm, n),
                   np.repeat(c.principal_point_mm, n, axis=0))
    return replace(b, cameras=cams, photos=replace(b.photos, camera=np.arange(n)),
                   settings=replace(b.settings, datum="free",
                                    calibration_free=(("c", "x0", "y0"),) * n))
