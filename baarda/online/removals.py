"""Observations taken out of the on-line bundle (online/bundle.py): an image point, several
at once, a point set aside until its next ray, a control point, a GNSS position, a photo;
the points and photos the block no longer determines leave it with them, and the block is
factored again (`_removed`); a removal that leaves it undetermined is not made."""

from __future__ import annotations

import time

from baarda.errors import GeometryError
from baarda.online.addition_tests import AdditionTests
from baarda.online.answers import Answer
from baarda.online.entering import leaving
from baarda.online.factorised import undetermined_photo
from baarda.online.measurements import HELD, IN, REMOVED


class Removals(AdditionTests):
    """The removals of an OnlineBundle (a base of it)."""

    def _answer(self, **kw) -> Answer:
        """The step's Answer (OnlineBundle)."""
        raise NotImplementedError

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
                bad = undetermined_photo(e)
                if bad is None or not m.photo_in[bad]:
                    m.restore(before)
                    self._refactor()
                    raise GeometryError(f"{what} cannot be taken out: {e}") from None
                m.photo_in[bad] = False
                left.append(m.photo_ids[bad])
                leaving(self.m)
        else:
            m.restore(before)
            self._refactor()
            raise GeometryError(f"{what} cannot be taken out: the block falls apart")
        return self._answer(action="remove", what=what, changed=tuple(changed),
                            refactorised=True, seconds=time.perf_counter() - t0,
                            note=f"photo(s) {', '.join(left)} no longer determined: held"
                            if left else "")
