"""Free networks (no control: BAL, COLMAP, AICON): the datum by minimal constraints.

Without other observations the seven datum parameters (translation, rotation, scale) are
fixed by holding the six exterior-orientation unknowns of one photo and one
projection-centre coordinate of a second photo (the coordinate with the largest difference
from the first photo); distances fix the scale, and then the first photo alone is held.
GNSS positions and IMU attitudes fix part or all of the datum (bundle/datum_share.py):
constraints then hold only the directions they leave free, on unknowns of the same two
photos (minimal_constraints), and none where they fix the whole datum.  Held unknowns get
zero columns in the Jacobian and a direct observation of weight `HOLD` (BundleProblem,
Linearization.wf), so their corrections and cofactors are exactly zero up to 1/HOLD and
the rest of the normal equations is untouched.

How it counts: the datum observations are not observations and the held unknowns are not
unknowns (SchurSystem.n_fixed), so redundancy = n - (u - c) with c the number of held
unknowns (7 with neither distances nor GNSS/IMU), the redundancy of any minimal-constraint
solution.  Residuals, sigma0, redundancy numbers, w-tests and MDBs of the observations do
not depend on which minimal datum is chosen; standard deviations of orientations and
points do (they refer to the chosen datum).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.bundle.datum_share import DatumShare, datum_share, minimal_constraints
from baarda.bundle.result_text import EO_NAMES
from baarda.errors import GeometryError


def choose_datum(block: Block, first: int = 0) -> tuple[int, int, int]:
    """(photo held fully, second photo, its coordinate 0/1/2 held) from the approximations:
    the coordinate with the largest absolute difference from the first photo, or as the
    block's source states it (settings.free_datum: DBAT's dependent relative orientation,
    the largest signed difference among the coordinates it allows)."""
    eo = block.photos.eo
    if len(eo) < 2:
        raise GeometryError("a free network needs at least two photos")
    axes = [0, 1, 2]
    d = np.abs(eo[:, :3] - eo[first, :3])
    if block.settings.free_datum is not None:
        photo, base = block.settings.free_datum
        first = block.photos.ids.index(photo)
        axes = [0, 1, 2] if base == "longest" else ["xyz".index(base)]
        d = eo[:, :3] - eo[first, :3]
    d = np.where(np.isin(np.arange(3), axes)[None, :], d, -np.inf)
    d[first] = -np.inf
    second, coord = np.unravel_index(int(np.argmax(d)), d.shape)
    if d[second, coord] <= 0:
        raise GeometryError("the approximate projection centres coincide: the scale of the "
                            "free network cannot be fixed")
    return first, int(second), int(coord)


class FreeBundleProblem(BundleProblem):
    """A BundleProblem without control whose datum is held by minimal constraints."""

    def __init__(self, block: Block, datum: tuple[int, int, int] | None = None,
                 diagnosis: tuple[str, ...] = (), inner: bool = False,
                 intersected: np.ndarray | None = None, share: DatumShare | None = None):
        if np.any(block.points.controlled):
            raise GeometryError("the block has control points: adjust it with its control "
                                "(a free-network datum would over-constrain it)")
        self.datum = choose_datum(block) if datum is None else datum
        a, b, k = self.datum
        self.scaled = bool(len(block.distances))  # a distance fixes the scale
        # GNSS positions and IMU attitudes fix part or all of the datum: constraints only
        # for what they leave free (bundle/datum_share.py; `share`: already computed)
        self.share = share if share is not None else observed_datum_share(block)
        if self.share is not None and self.share.carried:
            held = minimal_constraints(block, self.share, a, b)
        else:
            held = np.zeros((len(block.photos), 6), bool)
            held[a] = True
            if not self.scaled:
                held[b, k] = True
        # the inner datum moves the block along every datum direction: only where the
        # observations fix none of them
        self.inner = inner and (self.share is None or not self.share.carried)
        self.inner_refused = inner and not self.inner
        super().__init__(block, held=held, diagnosis=diagnosis, intersected=intersected)

    def _not_converged_notes(self) -> list[str]:
        share = self.share
        if share is None or not share.carried:
            return []
        worst = float(share.sd.max())
        return [f"the {share.by} carry {share.carried} of the {share.d} datum parameters "
                f"(no constraints hold those; the weakest of them to +- {worst:.3g} m at the "
                f"block's extent {share.extent:.3g} m): where the approximations are in "
                "another datum than theirs the block has to turn, shift or scale far to meet "
                "them; give approximations in their frame, adjust with control (--datum "
                "control and control points), or adjust without them"]

    def _held_text(self) -> str:
        """The unknowns the constraints hold, in words."""
        ids = self.block.photos.ids
        assert self.held is not None
        parts = [f"{', '.join(EO_NAMES[c] for c in np.flatnonzero(row))} of photo {ids[i]}"
                 for i, row in enumerate(self.held) if row.any()]
        return " and ".join(parts)

    def datum_text(self) -> str:
        a, b, k = self.datum
        ids = self.block.photos.ids
        invariant = "the observations' statistics do not depend on the datum"
        share = self.share
        if share is not None and share.carried:
            left = share.free.shape[1]
            held = (f"minimal constraints hold the {left} direction(s) they leave free: "
                    f"{self._held_text()}" if left else "no constraints")
            return (f"datum: FREE NETWORK (no control): the {share.by} fix {share.carried} of "
                    f"its {share.d} datum parameters; {held}; coordinates and their standard "
                    "deviations refer to this datum" + (
                        " (not the inner datum of the points: the observations hold part of "
                        "the datum)" if self.inner_refused else "") + "; " + invariant
                    + ("" if left else " (there is no choice)"))
        scale = ("the scale by the distance observations" if self.scaled else
                 f"{'XYZ'[k]}0 of photo {ids[b]} (scale)")
        if self.inner:
            return ("datum: FREE NETWORK (no control) in the INNER DATUM of all adjusted "
                    "points: adjusted with minimal constraints (photo "
                    f"{ids[a]} held and {scale}), coordinates and standard deviations then "
                    "S-transformed to the datum in which the points move least from their "
                    "approximations (" + ("6 parameters, the distances fix the scale"
                                          if self.scaled else "7 parameters") + "); "
                    + invariant)
        return (f"datum: FREE NETWORK (no control): minimal constraints, photo {ids[a]} held "
                f"(its six orientation unknowns) and {scale}; coordinates and their standard "
                "deviations refer to this datum; " + invariant)


def observed_datum_share(block: Block) -> DatumShare | None:
    """What the GNSS positions and IMU attitudes of `block` fix of its datum (None without
    them)."""
    return datum_share(block) if len(block.gnss) or len(block.imu) else None


def without_weak_datum_observations(block: Block, share: DatumShare | None = None) -> Block:
    """The block without its GNSS positions and IMU attitudes when they fix a datum direction
    only weakly (bundle/datum_share.py: three GNSS positions close to a line and the roll
    about it): holding that direction by a constraint would over-constrain them (statistics
    that depend on the constraint), leaving it to them a datum fixed only in name.  A note
    says which direction and what to do.  `share`: datum_share(block), where computed."""
    if not (len(block.gnss) or len(block.imu)):
        return block
    share = share if share is not None else datum_share(block)
    if not share.weak:
        return block
    from baarda.block.photo_block import no_gnss, no_imu

    what = " and ".join(s for s in share.sources if s != "distances")
    return replace(block, gnss=no_gnss(), imu=no_imu(), notes=list(block.notes) + [
        f"free network: the {what} left out of the adjustment: they fix the "
        f"{'; '.join(share.weak)} only weakly, so they cannot carry the datum and minimal "
        "constraints would over-constrain them (the statistics would depend on the photo "
        f"held); the {share.d} datum parameters are held by minimal constraints instead.  "
        "Use them with --datum control (their datum, if it converges), or add control "
        "points"])


def adjust_free(block: Block, datum: tuple[int, int, int] | None = None,
                **kwargs) -> BundleResult:
    """Bundle adjustment of a block without control (minimal-constraint datum, see above)."""
    return FreeBundleProblem(block, datum).fit(**kwargs)


def drop_points_behind(block: Block) -> tuple[Block, int]:
    """The block without observations whose point lies behind the camera at the
    approximations (the adjustment keeps every point in front); returns (block, count)."""
    from baarda.bundle.collinearity import camera_depth

    im = block.image
    xyz = block.points.xyz[im.point]
    known = np.isfinite(xyz).all(axis=1)  # points without approximations cannot be judged
    ok = ~known | (camera_depth(block.photos.eo[im.photo], np.where(known[:, None], xyz, 0))
                   > 0)
    if ok.all():
        return block, 0
    out = block.select_image(ok)
    before, after = block.rays(), out.rays()
    lost = [block.points.ids[j] for j in np.flatnonzero((after < 2) & (after < before))]
    out.notes.append(f"{int((~ok).sum())} observation(s) of points behind the camera at the "
                     "approximations left out" + (
                         f"; {len(lost)} point(s) left with fewer than two rays by it: "
                         + ", ".join(lost[:10]) + (f" and {len(lost) - 10} more"
                                                   if len(lost) > 10 else "")
                         if lost else ""))
    return out, int((~ok).sum())
