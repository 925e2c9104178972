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

import time
from dataclasses import replace

import numpy as np

from baarda.block.camera import with_camera
from baarda.block.photo_block import Block, Cameras
from baarda.bundle.bundle_problem import SOLVE
from baarda.bundle.resection import resect
from baarda.errors import GeometryError
from baarda.kinds import CONTROL, GNSS, IMAGE, IMU
from baarda.linalg.threads import single_threaded_blas
from baarda.online.answers import Answer, Change, ComponentTest, rejected
from baarda.online.approximations import prepared, prune
from baarda.online.entering import entering, held_words, leaving, mark_in
from baarda.online.factorised import Factored, Key, undetermined_photo
from baarda.online.measurements import HELD, IN, Measurements
from baarda.online.removals import Removals
from baarda.options import FREE_DATUMS, SolveOptions, TestOptions
from baarda.quality.distributions import b_method
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.quality.statistics import R_MIN

MAX_ROWS = 120  # rows added before the block is factored again
LINEAR_LIMIT = 3e-4  # corrections (angles rad, positions / flying height) that refactor


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
    if s.datum in FREE_DATUMS and (block.points.controlled.any() or len(block.gnss)):
        return ("the on-line bundle does not take control or GNSS positions in a free "
                "network (datum free): give them with datum = \"control\"")
    fixed = np.flatnonzero((block.points.sigma == 0).any(axis=1))
    if len(fixed):
        return (f"fixed control (sigma 0) is not supported on-line (point "
                f"{block.points.ids[fixed[0]]}" + (f" and {len(fixed) - 1} more" if
                                                    len(fixed) > 1 else "")
                + "): give it a small standard deviation, or adjust with baarda adjust")
    return ""


class OnlineBundle(Removals):
    """A bundle block that grows one measurement at a time (module docstring); its
    removals, the tests of an addition and the factorisation are its bases
    (online/removals.py, online/addition_tests.py, online/factorised.py).

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
        self.free = s.datum in FREE_DATUMS
        self.tests = tests or TestOptions.resolve(s)
        self._bm = b_method(self.tests.alpha0, self.tests.beta0)
        self.max_rows = int(max_rows)
        self.linear_limit = float(linear_limit)
        self.solve_options = solve
        self.m = Measurements(block)
        self._datum: tuple[int, int, int] | None = None  # free network: universe photos
        self._f: Factored | None = None
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
            m.resected.discard(i)
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
        if kind in (IMAGE.name, CONTROL.name):
            j = m.im_point[key[1]] if kind == IMAGE.name else key[1]
            cand = [(IMAGE.name, r, c) for r in m.rows_of_point[j] for c in range(2)]
            cand += [(CONTROL.name, j, c) for c in range(3)]
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
        st = {IMAGE.name: m.im_status, CONTROL.name: m.ctrl_status, GNSS.name: m.g_status,
              IMU.name: m.i_status}[kind]
        return st[u] == IN

    def is_in(self, kind: str, photo: str, point: str) -> bool:
        """Whether an observation is in the block now (image point `point` on `photo`, the
        control of `point`, the GNSS position of `photo`)."""
        m = self.m
        if kind == CONTROL.name:
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
        m.resected.add(i)
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
                bad = undetermined_photo(e)
                if bad is None or bad not in photos:
                    break
                photos.discard(bad)
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

    def _twins(self, tested: list[ComponentTest], changed=()) -> tuple[tuple, ...]:
        """What the test cannot tell from the step's most likely error (Answer.remeasure:
        the largest |w| among the rejected and the verdicts changed to reject)
        (`inseparable`): ((kind, photo, point, component), ...)."""
        rej = rejected(tested, changed)
        if not rej:
            return ()
        t = rej[0]
        return tuple(k for k, _ in self.inseparable(t.kind, t.photo, t.point, t.component))


def _merge(a: list[Change], b: list[Change]) -> list[Change]:
    """Changes of one step found twice (around the addition, then at the factorisation)."""
    by: dict[tuple, Change] = {}
    for c in a + b:
        key = (c.kind, c.photo, c.point, c.component)
        first = by.get(key)
        by[key] = c if first is None else replace(c, before=first.before)
    return [c for c in by.values() if c.before != c.after]
