"""The growing bundle block: every measurement tested the moment it is made (issue 33).

    ob = OnlineBundle(block)               # the block as far as it is measured
    a = ob.add_image_point("01004", "002005", x, y)    # an Answer: the test, the verdict
    a = ob.add_photo("01005", {"002005": (x, y), ...})  # a photo's points, tested together
    ob.add_control(...); ob.add_gnss(...); ob.remove_image_point(...)
    ob.inseparable("image", "01004", "002005", "y")    # what the test cannot tell it from
    ob.set_aside("002005")                 # out until its next ray (which may tell)
    qc = ob.result()                       # the Assessment of the block as it is now

Each addition is tested before it is taken in: its predicted misclosure with the variance
of the prediction, and after inclusion its residual, redundancy number, w and MDB in the
block with it (online/lowrank.py: a few solves with the last factorisation, no selected
inverse); a point's first ray is held until its second arrives (then both are tested), a
photo until the block determines it (MIN_PHOTO_POINTS of its points), the first adjustment
until the control fixes the block.  The observations whose verdict the addition changed are
looked for among those that share a photo or a point with it and those added since the last
factorisation; every `max_rows` added rows, when the corrections since exceed
`linear_limit`, at every removal and at `result()` the block is factored again at its
Gauss-Newton solution (warm-started), and every verdict is checked.  A group of more rows
than `max_rows` (a photo of hundreds of points) goes straight into a new factorisation.
What enters and leaves the block is online/entering.py's bookkeeping.
After any sequence of additions and removals `result()` is the batch adjustment of the same
observations (tests/online/test_equivalence.py).
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, replace

import numpy as np

from baarda.block.camera import with_camera
from baarda.block.photo_block import Block, Cameras
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import SOLVE, BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.bundle.resection import resect
from baarda.errors import GeometryError
from baarda.kinds import CONTROL, GNSS, IMAGE, IMU
from baarda.linalg.threads import single_threaded_blas
from baarda.online.answers import Answer, Change, ComponentTest, rejected, verdicts
from baarda.online.approximations import intersect, prepared, prune, refine
from baarda.online.entering import entering, held_words, leaving, mark, mark_in
from baarda.online.lowrank import LowRank, Rows, quad_diag, times
from baarda.online.measurements import HELD, IN, REMOVED, Measurements
from baarda.online.rows import factor_rows, group_rows, take
from baarda.options import SolveOptions, TestOptions
from baarda.quality.distributions import b_method
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.quality.statistics import R_MIN, residual_cofactors, w_tests

MAX_ROWS = 120  # rows added before the block is factored again
CHUNK = 256  # rows solved together for a large group's predictions
LINEAR_LIMIT = 3e-4  # corrections (angles rad, positions / flying height) that refactor
COMPONENTS = {k.name: k.components for k in (IMAGE, CONTROL, GNSS, IMU)}
Key = tuple[str, int, int]  # (kind, universe index, component number)


@dataclass
class _Factored:
    """The block at its last factorisation: the problem, its solution and what the
    low-rank update needs of it."""

    problem: BundleProblem
    result: BundleResult
    model: BundleModel
    keys: list
    flat_of: dict
    q0: np.ndarray  # adjusted cofactors of every component (flat)
    v0: np.ndarray  # residuals
    sigma: np.ndarray
    frame_of: np.ndarray  # universe photo -> frame (-1)
    elim_of: np.ndarray  # universe point -> eliminated point (-1)
    by_photo: dict  # universe photo -> flat components on it
    by_point: dict
    lowrank: LowRank


def refusal(block: Block) -> str:
    """Why the on-line bundle does not take a block ("" where it does): unknowns of the
    whole block (GNSS shifts and drifts, an estimated IMU boresight), distances, fixed
    control, a free network with control or GNSS; each with what to do instead."""
    s = block.settings
    whole = [w for w, on in (
        ("a GNSS shift of the block ([gnss] offsets = \"block\")", s.gnss_offsets == "block"),
        ("GNSS shifts per strip ([gnss] offsets = \"strip\")", s.gnss_offsets == "strip"),
        ("GNSS drifts per strip ([gnss] drift = true)", bool(s.gnss_drift)),
        ("an estimated IMU boresight ([imu] boresight = \"estimated\")",
         s.imu_boresight != "fixed")) if on]
    if whole:
        return (f"the on-line bundle does not estimate {' and '.join(whole)}: they are "
                "unknowns of the whole block, not of a photo; adjust the block with baarda "
                "adjust, or measure on-line with GNSS positions and IMU attitudes taken as "
                "they are ([gnss] offsets = \"none\", drift = false, [imu] boresight = "
                "\"fixed\")")
    if len(block.distances):
        return ("the on-line bundle does not take distances: adjust the block with baarda "
                "adjust, or measure on-line without them")
    if s.datum in ("free", "inner") and (block.points.controlled.any() or len(block.gnss)):
        return ("a free network (datum free) has no control and no GNSS positions: give "
                "them with datum = \"control\"")
    fixed = np.flatnonzero((block.points.sigma == 0).any(axis=1))
    if len(fixed):
        return (f"fixed control (sigma 0) is not supported on-line (point "
                f"{block.points.ids[fixed[0]]}" + (f" and {len(fixed) - 1} more" if
                                                    len(fixed) > 1 else "")
                + "): give it a small standard deviation, or adjust with baarda adjust")
    return ""


class OnlineBundle:
    """A bundle block that grows one measurement at a time (module docstring).

    block: what is measured so far, as read (put in the local frame of its CRS, photos
    without approximations resected where they can be: `approximations.prepared`); tests:
    alpha0, beta0 (default the block's); max_rows: rows added before the normal equations
    are factored again (0: after every step, every test then on the exact solution);
    linear_limit:
    corrections since the last factorisation (angles rad, positions / flying height) beyond
    which it is done at once.
    The datum is the control (or GNSS positions) or, for a free network (settings.datum
    "free" or "inner": COLMAP, BAL, AICON), minimal constraints as `baarda adjust` holds
    them (bundle/free_network.py): the first adjustment's choice of photos (`choose_datum`)
    held at its values from then on (chosen again only when a removal takes a datum photo
    out); the observations' r, w and MDB do not depend on the minimal datum, coordinates
    and their standard deviations do.  GNSS shifts, drifts and an estimated boresight,
    fixed control (sigma 0) and distances are not supported on-line.
    """

    def __init__(self, block: Block, tests: TestOptions | None = None, *,
                 max_rows: int = MAX_ROWS, solve: SolveOptions = SOLVE,
                 linear_limit: float = LINEAR_LIMIT):
        why = refusal(block)
        if why:
            raise ValueError(why)
        block = prepared(block)
        s = block.settings
        self.free = s.datum in ("free", "inner")
        self.tests = tests or TestOptions.resolve(s)
        self._bm = b_method(self.tests.alpha0, self.tests.beta0)
        self.max_rows = int(max_rows)
        self.linear_limit = float(linear_limit)
        self.solve_options = solve
        self.m = Measurements(block)
        self._datum: tuple[int, int, int] | None = None  # free network: universe photos
        self._f: _Factored | None = None
        self._ycol: dict = {}  # ("photo"|"point", universe index) -> first new-unknown column
        self._y0 = np.zeros(0)
        self._pending: list[Key] = []
        self._verdict: dict[Key, str] = {}
        self._keys_told: dict[tuple, Key] = {}
        self.steps = 0
        self.answers: list[Answer] = []
        self.first: Answer | None = None  # the first adjustment, once there is one
        self._why_not = "nothing measured"
        self._start(time.perf_counter(), "the block as given")

    # ================================================================ public API
    @property
    def started(self) -> bool:
        """Whether the block has been adjusted (its control fixes it)."""
        return self._f is not None

    def add_image_point(self, photo: str, point: str, x_mm: float, y_mm: float,
                        sigma_um: float | None = None) -> Answer:
        """Measure point `point` on photo `photo` at (x, y) mm (sigma: the project's)."""
        t0 = time.perf_counter()
        i = self.m.photo_index(photo)
        self.m.image(i, self.m.point_index(point), (x_mm, y_mm), self._image_sigma(sigma_um))
        return self._added(t0, f"point {point} on photo {photo}")

    def add_photo(self, photo: str, points: dict, *, camera: str | None = None,
                  eo=None, strip=None, gnss=None, sigma_um: float | None = None) -> Answer:
        """A photo with its image points {point: (x, y) mm or (x, y, sigma µm)}, tested
        together.  A photo the block knows keeps its approximations unless `eo` is given
        (X0, Y0, Z0 m, omega, phi, kappa rad); a new one needs `camera` (default: the only
        camera) and gets its orientation by resection when `eo` is None.  gnss: (xyz,
        sigma) of its GNSS position."""
        t0 = time.perf_counter()
        m = self.m
        i = m.photo_at.get(photo)
        if i is None:
            cams = list(m.cameras.ids)
            if camera is None and len(cams) > 1:
                raise ValueError(f"photo {photo}: name its camera ({', '.join(cams)})")
            c = 0 if camera is None else cams.index(camera) if camera in cams else None
            if c is None:
                raise ValueError(f"photo {photo}: camera {camera} is not known "
                                 f"({', '.join(cams)})")
            i = m.photo(photo, c, strip if strip is not None else "",
                        np.full(6, np.nan) if eo is None else eo)
        elif eo is not None:
            m.photo_eo[i] = np.asarray(eo, float).copy()
            m.changed()
        for pid, obs in points.items():
            obs = tuple(obs)
            sig = self._image_sigma(obs[2] if len(obs) > 2 else sigma_um)
            m.image(i, m.point_index(str(pid)), obs[:2], sig)
        if gnss is not None:
            m.gnss(i, gnss[0], gnss[1])
        return self._added(t0, f"photo {photo}, {len(points)} image point(s)")

    def add_camera(self, cameras: Cameras, index: int = 0, free: tuple[str, ...] = ()) -> Answer:
        """A camera for photos still to come: camera `index` of `cameras` (a Block's),
        its interior orientation and model held as given.  Refused: an id the block has,
        parameters to be estimated (`free`, its block's settings.calibration_free: new
        unknowns of the whole block: adjust with baarda adjust).  A block already adjusted
        is factored again with it (the same solution)."""
        t0 = time.perf_counter()
        cid = cameras.ids[index]
        if cid in self.m.cameras.ids:
            raise ValueError(f"camera {cid} is in the block already")
        if free:
            raise ValueError(f"camera {cid}: the on-line bundle does not estimate the "
                             f"parameters of a new camera ({', '.join(free)})")
        self.m.cameras = with_camera(self.m.cameras, cameras, index)
        held = self.m.settings.calibration_free
        if held is not None:  # the new camera's parameters held
            self.m.settings = replace(self.m.settings, calibration_free=(*held, ()))
        changed = self._refactor() if self._f is not None else []
        return self._answer(action="camera", what=f"camera {cid}", changed=tuple(changed),
                            refactorised=self._f is not None,
                            seconds=time.perf_counter() - t0)

    def add_control(self, point: str, xyz, sigma) -> Answer:
        """Control coordinates X, Y, Z (m) of a point with their sigmas (NaN: not
        observed)."""
        t0 = time.perf_counter()
        sigma = np.broadcast_to(np.asarray(sigma, float), (3,))
        if (sigma == 0).any():
            raise ValueError("fixed control (sigma 0) is not supported on-line")
        self.m.control(self.m.point_index(point), xyz, sigma)
        return self._added(t0, f"control point {point}")

    def add_gnss(self, photo: str, xyz, sigma) -> Answer:
        """The GNSS antenna position (m) of a photo with its sigmas."""
        t0 = time.perf_counter()
        self.m.gnss(self.m.photo_index(photo), xyz, sigma)
        return self._added(t0, f"GNSS position of photo {photo}")

    def remove_image_point(self, photo: str, point: str) -> Answer:
        """Take an image point out (both coordinates)."""
        t0 = time.perf_counter()
        m = self.m
        i, j = m.photo_index(photo), m.point_at.get(point)
        rows = [r for r in m.rows_of_photo[i] if m.im_point[r] == j
                and m.im_status[r] != REMOVED]
        if j is None or not rows:
            raise ValueError(f"point {point} is not measured on photo {photo}")
        return self._removed(t0, f"point {point} on photo {photo}",
                             lambda: m.im_status.__setitem__(rows[0], REMOVED))

    def remove_image_points(self, pairs) -> Answer:
        """Take several image points out at once, [(photo, point), ...] (one factorisation:
        what a reconstruction's later snapshot no longer has)."""
        t0 = time.perf_counter()
        m = self.m
        rows = []
        for photo, point in pairs:
            i, j = m.photo_index(photo), m.point_at.get(point)
            live = [r for r in m.rows_of_photo[i] if m.im_point[r] == j
                    and m.im_status[r] != REMOVED]
            if j is None or not live:
                raise ValueError(f"point {point} is not measured on photo {photo}")
            rows.append(live[0])

        def apply():
            for r in rows:
                m.im_status[r] = REMOVED
        return self._removed(t0, f"{len(rows)} image point(s)", apply)

    def set_aside(self, point: str) -> Answer:
        """Take a point out of the block until its next ray: its rays and its control are
        held and come in again, every component tested, with the next ray measured on it.
        For a point whose rays the test cannot tell apart (`inseparable`: the two rays of a
        two-ray point, the x of three rays along one strip): a ray from another direction
        may tell which one is wrong, where re-measuring all of them would lose the good
        ones."""
        t0 = time.perf_counter()
        m = self.m
        j = m.point_at.get(point)
        if j is None or not m.live_rays(j):
            raise ValueError(f"point {point} is not measured")

        def apply():
            m.aside[j] = max(m.rows_of_point[j])
            m.point_in[j] = False
        return self._removed(t0, f"point {point} (set aside until its next ray)", apply)

    def waiting(self, point: str) -> bool:
        """Whether a point set aside (`set_aside`) still waits for its next ray."""
        j = self.m.point_at.get(point)
        return j is not None and self.m.waiting(j)

    def inseparable(self, kind: str, photo: str, point: str, component: str,
                    threshold: float = RHO_INSEPARABLE) -> list[tuple[tuple, float]]:
        """The observations in the block whose w-test cannot be told from this one's: |rho|
        of the two w's at least `threshold` (quality/separability.py), among the components
        of the same point (its rays and its control) or, for GNSS and IMU, of the same
        photo; [((kind, photo, point, component), rho)], largest |rho| first.  From the
        residuals' cofactors in the block as it is now (the factorisation and the rows added
        since: one solve with the factor for the components involved)."""
        key = self._keys_told.get((kind, photo, point, component))
        if self._f is None or key is None or not self._in(key):
            raise ValueError(f"{kind} {component} of {point or photo} is not in the block")
        m = self.m
        if kind in ("image", "control"):
            j = m.im_point[key[1]] if kind == "image" else key[1]
            cand = [("image", r, c) for r in m.rows_of_point[j] for c in range(2)]
            cand += [("control", j, c) for c in range(3)]
        else:
            i = (m.g_photo if kind == GNSS.name else m.i_photo)[key[1]]
            cand = [(k, r, c) for k, rows in ((GNSS.name, m.gnss_of(i)), (IMU.name, m.imu_of(i)))
                    for r in rows for c in range(3)]
        pend = set(self._pending)
        cand = [k for k in cand if k != key and self._in(k)
                and (k in pend or k in self._f.flat_of)]
        q = self._qvv([key] + cand)
        d = np.diag(q)
        out = []
        for n, k in enumerate(cand, start=1):
            s2 = self._sigma_of(k) ** 2
            if d[n] < R_MIN * s2 or d[0] <= 0:
                continue  # not tested (r below 0.001)
            rho = float(q[0, n] / np.sqrt(d[0] * d[n]))
            if abs(rho) >= threshold:
                out.append((self._label(k), rho))
        return sorted(out, key=lambda t: -abs(t[1]))

    def remove_control(self, point: str) -> Answer:
        t0 = time.perf_counter()
        m = self.m
        j = m.point_at.get(point)
        if j is None or m.ctrl_status[j] not in (HELD, IN):
            raise ValueError(f"point {point} has no control")

        def apply():
            m.ctrl_status[j] = REMOVED
            m.point_role[j] = "tie"
            m.changed()
        return self._removed(t0, f"control of point {point}", apply)

    def remove_gnss(self, photo: str) -> Answer:
        t0 = time.perf_counter()
        m = self.m
        rows = m.gnss_of(m.photo_index(photo))
        if not rows:
            raise ValueError(f"photo {photo} has no GNSS position")
        return self._removed(t0, f"GNSS position of photo {photo}",
                             lambda: m.g_status.__setitem__(rows[0], REMOVED))

    def remove_photo(self, photo: str) -> Answer:
        """Every observation of a photo."""
        t0 = time.perf_counter()
        m = self.m
        i = m.photo_index(photo)

        def apply():
            for r in m.rows_of_photo[i]:
                m.im_status[r] = REMOVED
            for r in m.gnss_of(i):
                m.g_status[r] = REMOVED
            for r in m.imu_of(i):
                m.i_status[r] = REMOVED
        return self._removed(t0, f"photo {photo}", apply)

    def result(self):
        """The Assessment of the block as it is now (every observation in it tested): the
        batch adjustment of the same observations, warm-started."""
        from baarda.bundle.bundle_quality import assess

        if self._f is None:
            raise GeometryError("the block cannot be adjusted yet: " + self._why_not)
        if self._pending:
            self._refactor()
        return assess(self._f.result, self.tests)

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """(eo (n_photos, 6), xyz (n_points, 3)) of every photo and point given so far, as
        the block estimates them now (NaN: not in the block), in the order given."""
        return self._current()

    def status(self) -> str:
        """The block now, in words: what is in it and held, sigma0 and the rejected
        observations at the last factorisation (the answers since say the rest)."""
        m = self.m
        held = sum(st == HELD for st in m.im_status)
        head = (f"{sum(m.photo_in)} of {len(m.photo_ids)} photos and {sum(m.point_in)} points "
                f"in the block, {sum(st == IN for st in m.im_status)} image points ({held} "
                "held)")
        if self._f is None:
            return head + "; not adjusted yet: " + self._why_not
        res = self._f.result
        rej = [k for k, v in self._verdict.items() if v == "reject" and self._in(k)]
        lines = [head, f"at the last factorisation: redundancy {res.redundancy}, sigma0 "
                 f"{res.sigma0:.4f}; {len(self._pending)} component(s) added since"]
        if rej:
            lines.append(f"rejected now ({len(rej)}): " + ", ".join(
                " ".join(x for x in self._label(k) if x) for k in rej[:10])
                + (" ..." if len(rej) > 10 else ""))
        return "\n".join(lines)

    def _in(self, key: Key) -> bool:
        kind, u, _ = key
        m = self.m
        st = {"image": m.im_status, "control": m.ctrl_status, GNSS.name: m.g_status,
              IMU.name: m.i_status}[kind]
        return st[u] == IN

    def is_in(self, kind: str, photo: str, point: str) -> bool:
        """Whether an observation is in the block now (image point `point` on `photo`, the
        control of `point`, the GNSS position of `photo`)."""
        m = self.m
        if kind == "control":
            j = m.point_at.get(point)
            return j is not None and m.ctrl_status[j] == IN
        i = m.photo_at.get(photo)
        if i is None:
            return False
        if kind == GNSS.name:
            return any(m.g_status[r] == IN for r in m.gnss_of(i))
        j = m.point_at.get(point)
        return any(m.im_point[r] == j and m.im_status[r] == IN for r in m.rows_of_photo[i])

    @property
    def photo_ids(self) -> list[str]:
        return list(self.m.photo_ids)

    @property
    def point_ids(self) -> list[str]:
        return list(self.m.point_ids)

    # ================================================================ steps
    def _image_sigma(self, sigma_um) -> np.ndarray:
        s = self.m.settings.sigma_image_um if sigma_um is None else float(sigma_um)
        if not s > 0:
            raise ValueError(f"image sigma {s} µm: must be positive")
        return np.full(2, s * 1e-3)

    def _answer(self, **kw) -> Answer:
        self.steps += 1
        a = Answer(step=self.steps, k_w=self._bm.k_w, **kw)
        self.answers.append(a)
        self.m.clear_fresh()
        return a

    @single_threaded_blas
    def _added(self, t0: float, what: str) -> Answer:
        if self._f is None:
            first = self._start(t0, what)
            if first is not None:
                return first
            return self._answer(action="add", what=what, held=tuple(held_words(self.m)),
                                note="the block cannot be adjusted yet: " + self._why_not,
                                seconds=time.perf_counter() - t0)
        group = entering(self.m, self._has_orientation)
        if not group:
            return self._answer(action="add", what=what, held=tuple(held_words(self.m)),
                                seconds=time.perf_counter() - t0)
        try:
            tested, changed, refac = self._take_in(group)
        except GeometryError as e:
            return self._answer(action="add", what=what, held=tuple(held_words(self.m)),
                                note=str(e), seconds=time.perf_counter() - t0)
        if not refac and (len(self._pending) > self.max_rows or self._nonlinear()):
            changed = _merge(changed, self._refactor())
            tested = self._exact(tested)
            refac = True
        return self._answer(action="add", what=what, tested=tuple(tested),
                            held=tuple(held_words(self.m)), changed=tuple(changed),
                            refactorised=refac, twins=self._twins(tested, changed),
                            seconds=time.perf_counter() - t0)

    @single_threaded_blas
    def _removed(self, t0: float, what: str, apply) -> Answer:
        """Take observations out (`apply` marks them removed): the points and photos the
        block no longer determines leave it, and it is factored again; a removal that leaves
        the block undetermined is not made (GeometryError)."""
        m = self.m
        before = m.snapshot()
        apply()
        if self._f is None:
            return self._answer(action="remove", what=what, seconds=time.perf_counter() - t0)
        leaving(self.m)
        if not any(b == IN and a != IN for b, a in zip(
                before[0] + before[1] + before[2] + before[3],
                m.im_status + m.ctrl_status + m.g_status + m.i_status, strict=True)):
            return self._answer(action="remove", what=what, note="it was not in the block",
                                seconds=time.perf_counter() - t0)
        left = []
        for _ in range(20):  # a photo the block no longer determines leaves it, again
            try:
                changed = self._refactor()
                break
            except GeometryError as e:
                bad = re.search(r"orientation of photo (\S+) is not determined", str(e))
                if bad is None or bad.group(1) not in m.photo_at:
                    m.restore(before)
                    self._refactor()
                    raise GeometryError(f"{what} cannot be taken out: {e}") from None
                m.photo_in[m.photo_at[bad.group(1)]] = False
                left.append(bad.group(1))
                leaving(self.m)
        else:
            m.restore(before)
            self._refactor()
            raise GeometryError(f"{what} cannot be taken out: the block falls apart")
        return self._answer(action="remove", what=what, changed=tuple(changed),
                            refactorised=True, seconds=time.perf_counter() - t0,
                            note=f"photo(s) {', '.join(left)} no longer determined: held"
                            if left else "")

    # ------------------------------------------------------------ approximations
    def _has_orientation(self, i: int) -> bool:
        """Whether photo i has an approximate orientation, resecting it from the block's
        points where it has none."""
        if np.isfinite(self.m.photo_eo[i]).all():
            return True
        eo, xyz = self._current()
        m = self.m
        rows = [r for r in m.rows_of_photo[i] if m.im_status[r] == HELD
                and m.point_in[m.im_point[r]]]
        if len(rows) < 3:
            return False
        cam = m.photo_cam[i]
        pp = m.cameras.principal_point_mm[cam]
        try:
            e, _ = resect(np.array([m.im_xy[r] for r in rows]) - pp,
                          xyz[[m.im_point[r] for r in rows]],
                          float(m.cameras.focal_mm[cam]))
        except GeometryError:
            return False
        m.photo_eo[i] = e
        m.changed()
        return True

    # ------------------------------------------------------------ the first adjustment
    @single_threaded_blas
    def _start(self, t0: float, what: str) -> Answer | None:
        """Adjust everything held once the control fixes the block: photos and points
        pruned to those the block determines, then the batch adjustment."""
        m = self.m
        if not m.im_status:
            return None
        photos = {i for i in range(len(m.photo_ids)) if np.isfinite(m.photo_eo[i]).all()}
        photos, points = prune(m, photos, set(range(len(m.point_ids))))
        note = "fewer than two photos are determined"
        for _ in range(20):  # a photo the adjustment finds undetermined is left out, again
            if len(photos) < 2:
                break
            for i in photos:
                m.photo_in[i] = True
            for j in points:
                m.point_in[j] = True
            mark_in(self.m)
            try:
                self._refactor(first=True)
                break
            except GeometryError as e:
                note = str(e)
                self._f = None
                for i in photos:
                    m.photo_in[i] = False
                for j in points:
                    m.point_in[j] = False
                leaving(self.m)
                bad = re.search(r"orientation of photo (\S+) is not determined", note)
                if bad is None or bad.group(1) not in m.photo_at:
                    break
                photos.discard(m.photo_at[bad.group(1)])
                photos, points = prune(m, photos, points)
        if self._f is None:
            self._why_not = note
            return self._answer(action="add", what=what, held=tuple(held_words(self.m)),
                                note="the block cannot be adjusted yet: " + note,
                                seconds=time.perf_counter() - t0)
        f = self._f
        q = self._stats(f)
        tested = [self._component(k, float("nan"), float("nan"), *s)
                  for k, s in zip(f.keys, zip(*q, strict=True), strict=True)]
        for k, t in zip(f.keys, tested, strict=True):
            self._verdict[k] = t.verdict
        ans = self._answer(action="first adjustment", what=what, tested=tuple(tested),
                           held=tuple(held_words(self.m)), refactorised=True,
                           twins=self._twins(tested),
                           note=f"first adjustment: {len(photos)} photos, {len(points)} "
                           f"points", seconds=time.perf_counter() - t0)
        self.first = ans
        return ans

    # ------------------------------------------------------------ factorisation
    def _current(self) -> tuple[np.ndarray, np.ndarray]:
        """Current estimates of every photo and point (approximations where not in the
        block; NaN where none).  New unknowns whose rows are not in the low-rank update yet
        (a large group on its way into a new factorisation) stand at their approximations."""
        eo, xyz, tie = self.m.arrays()
        eo = eo.copy()
        xyz = np.where(tie[:, None], np.nan, xyz)
        f = self._f
        if f is None:
            return eo, xyz
        res = f.result
        sol = f.lowrank.solution() if f.lowrank.r else None
        fr = np.flatnonzero(f.frame_of >= 0)
        e = res.state[0][f.frame_of[fr]]
        if sol is not None:
            e = e + sol.dxf[f.frame_of[fr]]
        eo[fr] = e
        pt = np.flatnonzero(f.elim_of >= 0)
        x = res.state[1][f.elim_of[pt]]
        if sol is not None:
            x = x + sol.dxp[f.elim_of[pt]]
        xyz[pt] = x
        y = self._y0.copy()
        if sol is not None:
            y[:len(sol.dy)] += sol.dy
        for (what, u), c in self._ycol.items():
            (eo if what == "photo" else xyz)[u] = y[c:c + (6 if what == "photo" else 3)]
        return eo, xyz

    def _globals(self) -> np.ndarray:
        f = self._f
        assert f is not None
        g = f.result.state[2] if len(f.result.state) == 3 else np.zeros(0)
        if f.lowrank.r and len(g):
            g = g + f.lowrank.solution().dxg
        return g

    def _refactor(self, first: bool = False) -> list[Change]:
        """Factor the block again at its Gauss-Newton solution (warm-started from the
        current estimates); returns the verdicts that changed since they were last told."""
        m = self.m
        eo, xyz = self._current()
        old_g = None if self._f is None else (self._f.problem.system.global_names,
                                              self._globals())
        block, maps = m.state_block(np.where(np.isfinite(eo), eo, 0.0), xyz)
        problem = self._problem(block, maps).with_solve_options(self.solve_options)
        start = (eo[maps.photos], xyz[maps.points[problem.elim_ids]])
        if problem.system.ng:
            g = np.concatenate([problem.calibration.start(), np.zeros(problem.gnss_imu.n)])
            if old_g is not None:
                at = {n: v for n, v in zip(old_g[0], old_g[1], strict=True)}
                g = np.array([at.get(n, v) for n, v in
                              zip(problem.system.global_names, g, strict=True)])
            start += (g,)
        result = problem.fit(start=None if first else start)
        model = BundleModel(result)
        keys = _flat_keys(problem, maps)
        nf = len(m.photo_ids)
        frame_of = np.full(nf, -1)
        frame_of[maps.photos] = np.arange(len(maps.photos))
        elim_of = np.full(len(m.point_ids), -1)
        elim_of[maps.points[problem.elim_ids]] = np.arange(len(problem.elim_ids))
        by_photo: dict[int, list[int]] = {}
        by_point: dict[int, list[int]] = {}
        for n, (kind, u, _c) in enumerate(keys):
            if kind == "image":
                by_photo.setdefault(m.im_photo[u], []).append(n)
                by_point.setdefault(m.im_point[u], []).append(n)
            elif kind == "control":
                by_point.setdefault(u, []).append(n)
            else:
                by_photo.setdefault((m.g_photo if kind == GNSS.name else m.i_photo)[u],
                                    []).append(n)
        q0 = np.maximum(model.adjusted_cofactor_diag(), 0.0)
        self._f = _Factored(
            problem=problem, result=result, model=model, keys=keys,
            flat_of={k: n for n, k in enumerate(keys)}, q0=q0, v0=model.residuals,
            sigma=model.sigma, frame_of=frame_of, elim_of=elim_of,
            by_photo={k: np.array(v) for k, v in by_photo.items()},
            by_point={k: np.array(v) for k, v in by_point.items()},
            lowrank=LowRank(result.factor))
        self._ycol, self._y0, self._pending = {}, np.zeros(0), []
        if first and not result.converged:
            raise GeometryError("the adjustment of the block did not converge: "
                                + "; ".join(result.notes[-1:]))
        if first:
            return []
        w, r, *_, mdb = self._stats(self._f)
        return self._changes(keys, w, r, mdb)

    def _problem(self, block: Block, maps) -> BundleProblem:
        """The bundle problem of the state block: with its control, or a free network held by
        the minimal constraints of the first adjustment (universe photos, `_datum`), chosen
        again (choose_datum) when one of its photos has left the block."""
        if not self.free:
            return BundleProblem(block)
        from baarda.bundle.free_network import FreeBundleProblem, choose_datum

        at = {int(u): n for n, u in enumerate(maps.photos)}
        d = self._datum
        if d is None or d[0] not in at or d[1] not in at:
            a, b, k = choose_datum(block)
            d = self._datum = (int(maps.photos[a]), int(maps.photos[b]), k)
        return FreeBundleProblem(block, datum=(at[d[0]], at[d[1]], d[2]),
                                 inner=self.m.settings.datum == "inner")

    def _nonlinear(self) -> bool:
        """Whether the rows since the factorisation moved the estimates so far from where
        they were linearised that the one-step solution is no longer exact enough: a
        position by more than LINEAR_LIMIT of the flying height or an angle by more than
        LINEAR_LIMIT rad (the error of the linearisation, c * LINEAR_LIMIT^2, then stays
        below 0.015 µm for c = 153 mm)."""
        f = self._f
        assert f is not None
        sol = f.lowrank.solution()
        h = f.problem.scale
        size = max(np.max(np.abs(sol.dxf[:, :3]), initial=0.0) / h,
                   np.max(np.abs(sol.dxf[:, 3:]), initial=0.0),
                   np.max(np.abs(sol.dxp), initial=0.0) / h)
        for (what, _u), c in self._ycol.items():
            d = sol.dy[c:c + (6 if what == "photo" else 3)]
            size = max(size, np.max(np.abs(d[:3])) / h,
                       np.max(np.abs(d[3:]), initial=0.0) if what == "photo" else 0.0)
        return size > self.linear_limit

    def _exact(self, tested: list[ComponentTest]) -> list[ComponentTest]:
        """The tests of components now in the factorisation, from its solution (the
        prediction before inclusion kept)."""
        f = self._f
        assert f is not None
        w, r, v, sv, mdb = self._stats(f)
        out = []
        for t in tested:
            n = f.flat_of.get(self._key_of(t))
            if n is None:
                out.append(t)
                continue
            out.append(self._component(f.keys[n], t.predicted, t.sigma_predicted, float(w[n]),
                                       float(r[n]), float(v[n]), float(sv[n]), float(mdb[n])))
        return out

    def _twins(self, tested: list[ComponentTest], changed=()) -> tuple[tuple, ...]:
        """What the test cannot tell from the step's most likely error (Answer.remeasure:
        the largest |w| among the rejected and the verdicts changed to reject)
        (`inseparable`): ((kind, photo, point, component), ...)."""
        rej = rejected(tested, changed)
        if not rej:
            return ()
        t = rej[0]
        return tuple(k for k, _ in self.inseparable(t.kind, t.photo, t.point, t.component))

    def _sigma_of(self, key: Key) -> float:
        m = self.m
        kind, u, c = key
        if kind == "image":
            return float(np.broadcast_to(m.im_sigma[u], (2,))[c])
        if kind == "control":
            return float(m.point_sigma[u][c])
        return float((m.g_sigma if kind == GNSS.name else m.i_sigma)[u][c])

    def _qvv(self, keys: list[Key]) -> np.ndarray:
        """The cofactors of the residuals of components in the block (in the factorisation
        or added since), (k, k).  For rows S of the factorisation and rows P added since
        (lowrank.py: H = N0^-1 A_P^T, W, R = diag(sigma_P^2)):
            Q_SS = R_S - a_S N0^-1 a_S^T + (a_S H) W (a_S H)^T,
            Q_PP = R_P W R_P,   Q_SP = -(a_S H) W R_P."""
        f = self._f
        assert f is not None
        lr = f.lowrank
        pend = {k: n for n, k in enumerate(self._pending)}
        s_at = [n for n, k in enumerate(keys) if k not in pend]
        p_at = [n for n, k in enumerate(keys) if k in pend]
        q = np.zeros((len(keys), len(keys)))
        sol = lr.solution() if lr.r else None
        z = None
        if s_at:
            flat = np.array([f.flat_of[keys[n]] for n in s_at])
            rows = factor_rows(f.problem, f.result.factor, flat)
            qs = np.diag(f.sigma[flat] ** 2) - times(rows, *lr.solve(rows))
            if sol is not None:
                z = times(rows, *lr.columns())
                qs = qs + z @ sol.w @ z.T
            q[np.ix_(s_at, s_at)] = qs
        if p_at:
            assert sol is not None  # pending rows: the low-rank part has rows
            pr = [pend[keys[n]] for n in p_at]
            q[np.ix_(p_at, p_at)] = sol.qvv[np.ix_(pr, pr)]
            if s_at:
                qsp = -(z @ sol.w)[:, pr] * (lr.sigma[pr] ** 2)[None, :]
                q[np.ix_(s_at, p_at)] = qsp
                q[np.ix_(p_at, s_at)] = qsp.T
        return 0.5 * (q + q.T)

    def _key_of(self, t: ComponentTest) -> Key:
        return self._keys_told[(t.kind, t.photo, t.point, t.component)]

    def _stats(self, f: _Factored):
        """w, r, v, sigma_v, mdb of every component at the factorisation (the quality
        layer's w_tests)."""
        qvv, r = residual_cofactors(f.q0, f.sigma)
        sv, w, mdb, _ = w_tests(f.v0, f.sigma, qvv, r, self._bm.delta0)
        return w, r, f.v0, sv, mdb

    def _changes(self, keys, w, r, mdb) -> list[Change]:
        out = []
        new = verdicts(np.asarray(w, float), np.asarray(r, float), self._bm.k_w)
        for k, v, wi, ri, mi in zip(keys, new, w, r, mdb, strict=True):
            before = self._verdict.get(k)
            if before is not None and before != v:
                out.append(self._change(k, before, v, float(wi), float(ri), float(mi)))
            self._verdict[k] = v
        return out

    # ------------------------------------------------------------ taking rows in
    def _take_in(self, group: dict) -> tuple[list[ComponentTest], list[Change], bool]:
        """Take a group of held observations in and test them: (the tests, the verdicts
        that changed, whether the block was factored again).  A group of more rows than a
        factorisation takes (a photo of hundreds of points) goes straight into a new
        factorisation (`_take_in_factored`); a smaller one is a low-rank update."""
        assert self._f is not None
        lr = self._f.lowrank
        ny0, ycol0 = len(self._y0), dict(self._ycol)
        y0 = self._new_unknowns(group)
        keys, rows = group_rows(self._f, self.m, self._ycol, group, y0)
        # the prediction from the block before: e - a dx, variance sigma^2 + a Q_xx a^T
        prev = lr.solution() if lr.r else None
        plain = np.all(rows.ycol < 0, axis=1)
        pred = rows.e.copy()
        var_old = np.zeros(len(rows))
        if prev is not None:
            z = times(rows, *lr.columns())
            pred = pred - z @ prev.we
            var_old = quad_diag(z, prev.w)
        if len(rows) > self.max_rows:
            return self._take_in_factored(group, keys, rows, plain, pred, var_old, ny0, ycol0)
        r0 = lr.r
        lr.add(rows, len(self._y0))
        try:
            sol = lr.solution()
        except GeometryError:
            lr.drop_last(len(rows), ny0)
            self._ycol, self._y0 = ycol0, self._y0[:ny0]
            raise GeometryError("held: these observations do not determine the new photo "
                                "or point yet") from None
        mark(self.m, group)
        self._pending += keys
        k = len(rows)
        sl = slice(r0, r0 + k)
        s2 = rows.sigma ** 2
        qvv = np.maximum(np.diag(sol.qvv)[sl], 0.0)
        r = qvv / s2
        sv, w, mdb, _ = w_tests(sol.v[sl], rows.sigma, qvv, r, self._bm.delta0)
        mdiag = np.diag(lr.m)[sl]
        sig_pred = np.where(plain, np.sqrt(s2 + mdiag - var_old), np.nan)
        pred = np.where(plain, pred, np.nan)
        tested = []
        for n, key in enumerate(keys):
            tested.append(self._component(key, float(pred[n]), float(sig_pred[n]),
                                          float(w[n]), float(r[n]), float(sol.v[r0 + n]),
                                          float(sv[n]), float(mdb[n])))
            self._verdict[key] = tested[-1].verdict
        # a step that brings more rows than a factorisation takes since the last one is
        # factored at once (_added), every verdict checked there: no neighbourhood first
        changed = [] if len(self._pending) > self.max_rows else \
            self._neighbourhood(group, keys, sol, r0)
        return tested, changed, False

    def _take_in_factored(self, group: dict, keys: list, rows: Rows, plain: np.ndarray,
                          pred: np.ndarray, var_old: np.ndarray, ny0: int, ycol0: dict
                          ) -> tuple[list[ComponentTest], list[Change], bool]:
        """A large group: its prediction's variance sigma^2 + a N0^-1 a^T - (the rows since
        the factorisation) for the rows between known photos and points (solves with the
        factor in chunks, nothing kept), then the block factored again with it, every
        component tested from that factorisation."""
        assert self._f is not None
        lr = self._f.lowrank
        sel = np.flatnonzero(plain)
        mdiag = np.zeros(len(rows))
        for a in range(0, len(sel), CHUNK):
            part = take(rows, sel[a:a + CHUNK])
            mdiag[sel[a:a + CHUNK]] = np.diagonal(times(part, *lr.solve(part)))
        s2 = rows.sigma ** 2
        # a row with a new photo or point has no prediction (mdiag not solved for it)
        sig_pred = np.sqrt(np.where(plain, s2 + mdiag - var_old, np.nan))
        pred = np.where(plain, pred, np.nan)
        before = self.m.snapshot()
        mark(self.m, group)
        try:
            changed = self._refactor()
        except GeometryError:
            self.m.restore(before)
            self._ycol, self._y0 = ycol0, self._y0[:ny0]
            self._refactor()
            raise GeometryError("held: these observations do not determine the new photo "
                                "or point yet") from None
        f = self._f
        assert f is not None
        w, r, v, sv, mdb = self._stats(f)
        tested = []
        for n, key in enumerate(keys):
            at = f.flat_of[key]
            tested.append(self._component(key, float(pred[n]), float(sig_pred[n]),
                                          float(w[at]), float(r[at]), float(v[at]),
                                          float(sv[at]), float(mdb[at])))
            self._verdict[key] = tested[-1].verdict
        return tested, changed, True

    def _neighbourhood(self, group: dict, new_keys: list, sol, r0: int) -> list[Change]:
        """Verdict changes among the factorisation's observations on the photos and points
        of the group and the rows added since the factorisation."""
        f, m = self._f, self.m
        assert f is not None
        photos = {m.im_photo[r] for r in group["image"]} | \
            {m.g_photo[r] for r in group[GNSS.name]} | {m.i_photo[r] for r in group[IMU.name]}
        points = {m.im_point[r] for r in group["image"]} | set(group["control"])
        flat = set()
        for i in photos:
            flat.update(f.by_photo.get(i, np.zeros(0, int)).tolist())
        for j in points:
            flat.update(f.by_point.get(j, np.zeros(0, int)).tolist())
        out = []
        if flat:
            flat = np.array(sorted(flat))
            rows = factor_rows(f.problem, f.result.factor, flat)
            q, v = f.lowrank.old_rows(rows, f.q0[flat], f.v0[flat])
            qvv, r = residual_cofactors(q, f.sigma[flat])
            _, w, mdb, _ = w_tests(v, f.sigma[flat], qvv, r, self._bm.delta0)
            out += self._changes([f.keys[n] for n in flat], w, r, mdb)
        if r0:
            sigma = f.lowrank.sigma[:r0]
            qvv = np.maximum(np.diag(sol.qvv)[:r0], 0.0)
            r = qvv / sigma ** 2
            _, w, mdb, _ = w_tests(sol.v[:r0], sigma, qvv, r, self._bm.delta0)
            out += self._changes(self._pending[:r0], w, r, mdb)
        return out

    def _new_unknowns(self, group: dict) -> np.ndarray:
        """Columns and approximations of the group's new photos and points: photos from
        their approximate orientation, points intersected, then both refined by
        Gauss-Newton with everything in the block held at its current estimate."""
        m = self.m
        if not (group["photos"] or group["points"]):
            return self._y0
        eo, xyz = self._current()
        cols = {}
        n = len(self._y0)
        for i in group["photos"]:
            cols[("photo", i)] = n
            n += 6
        for j in group["points"]:
            cols[("point", j)] = n
            n += 3
        if len(cols) == 0:
            return self._y0
        for i in group["photos"]:
            eo[i] = m.photo_eo[i]
        for j in group["points"]:
            xyz[j] = intersect(m, j, eo, group)
        assert self._f is not None
        if not refine(m, self._f.problem, self._globals(), group, eo, xyz):
            raise GeometryError("held: these observations do not determine the new photo "
                                "or point yet")
        y = np.zeros(n - len(self._y0))
        base = len(self._y0)
        for (what, u), c in cols.items():
            y[c - base:c - base + (6 if what == "photo" else 3)] = \
                eo[u] if what == "photo" else xyz[u]
        self._ycol.update(cols)
        self._y0 = np.concatenate([self._y0, y])
        return self._y0

    # ------------------------------------------------------------ labels
    def _label(self, key: Key) -> tuple[str, str, str, str]:
        m = self.m
        kind, u, c = key
        comp = COMPONENTS[kind][c]
        if kind == "image":
            return kind, m.photo_ids[m.im_photo[u]], m.point_ids[m.im_point[u]], comp
        if kind == "control":
            return kind, "", m.point_ids[u], comp
        ph = (m.g_photo if kind == GNSS.name else m.i_photo)[u]
        return kind, m.photo_ids[ph], "", comp

    def _component(self, key: Key, pred: float, sig_pred: float, w: float, r: float,
                   v: float, sv: float, mdb: float) -> ComponentTest:
        from baarda.online.answers import verdict

        kind, photo, point, comp = self._label(key)
        self._keys_told[(kind, photo, point, comp)] = key
        return ComponentTest(kind, photo, point, comp, pred, sig_pred, v, sv, r, w, mdb,
                             verdict(w, r, self._bm.k_w))

    def _change(self, key: Key, before: str, after: str, w: float, r: float,
                mdb: float) -> Change:
        kind, photo, point, comp = self._label(key)
        return Change(kind, photo, point, comp, before, after, w, r, mdb)


def _merge(a: list[Change], b: list[Change]) -> list[Change]:
    """Changes of one step found twice (around the addition, then at the factorisation)."""
    by: dict[tuple, Change] = {}
    for c in a + b:
        key = (c.kind, c.photo, c.point, c.component)
        first = by.get(key)
        by[key] = c if first is None else replace(c, before=first.before)
    return [c for c in by.values() if c.before != c.after]


def _flat_keys(problem: BundleProblem, maps) -> list:
    """The universe key of every component of a problem's flat observation vector."""
    keys = []
    for r in problem.obs:
        u = int(maps.image[r])
        keys += [("image", u, 0), ("image", u, 1)]
    sel = problem.layout.ctrl_sel
    ci, cc = np.divmod(sel, 3)
    for i, c in zip(ci, cc, strict=True):
        keys.append(("control", int(maps.points[problem.control[i]]), int(c)))
    gi = problem.gnss_imu
    for r in range(gi.n_gnss):
        keys += [(GNSS.name, int(maps.gnss[r]), c) for c in range(3)]
    for r in range(gi.n_imu):
        keys += [(IMU.name, int(maps.imu[r]), c) for c in range(3)]
    return keys
