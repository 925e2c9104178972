"""Issue 40: where Gauss-Newton diverges, Levenberg-Marquardt continues from the last sound
estimate (adjustment/solve.solve_continued) for the independent models as for the bundle."""

import copy

import numpy as np
import pytest

from baarda.errors import GeometryError
from baarda.independent.model_problem import ModelProblem


class _RefusedOnce(ModelProblem):
    """The model block, but its undamped normal equations at the second factorisation are
    'not positive definite' (as rounding in a nearly singular block makes them): the
    Gauss-Newton iteration diverges there."""

    def factorize(self, lin, damping=0.0):
        self.calls = getattr(self, "calls", 0) + 1
        if self.calls == 2 and not damping:
            raise GeometryError("the transformation of model 3 is not determined")
        return super().factorize(lin, damping)


def test_a_diverged_model_adjustment_continues_with_levenberg_marquardt(small3d):
    blk, _, plain = small3d
    flaky = copy.copy(plain.problem)
    flaky.__class__ = _RefusedOnce
    lines: list[str] = []
    res = flaky.fit(progress=lines.append)
    assert flaky.calls > 2 and plain.converged and not plain.notes
    assert res.converged and res.iterations > 2
    assert res.vtpv == pytest.approx(plain.vtpv, rel=1e-9)
    assert np.allclose(res.params, plain.params, atol=1e-7)
    assert len(res.notes) == 1 and res.notes[0].startswith("Gauss-Newton diverged at "
                                                           "iteration 2")
    assert "model 3" in res.notes[0]
    assert "Levenberg-Marquardt continued from the last sound estimate: converged" in \
        res.notes[0]
    assert any("Gauss-Newton diverged: Levenberg-Marquardt continues" in s for s in lines)
