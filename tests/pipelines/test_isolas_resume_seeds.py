"""pipelines.stages.isolas._Partial: an interrupted search resumes only from corrections made
from the same seeds. A sweep computed again under the same inputs (ti.h5 of an older version,
without boundary states, then `--force`d as the stage's warning says) brings seeds from time
integration that the partial file's corrections lack: the resume must start over, not index
past the corrections (IndexError). Residual: R(x, w) = x (x - 1), the lines x = 0 and x = 1."""
import numpy as np
import pytest

from hbm.isolas.search import Seed, search
from hbm.linalg.dense import DirectSolver
from pipelines.stages.isolas import _Partial
from support import unit_search_options


class Lines:
    def __call__(self, x, w, jacobian=True):
        R = np.array([x[0] * (x[0] - 1.0)])
        if not jacobian:
            return R
        return R, np.array([[2 * x[0] - 1.0]]), np.array([0.0])


def lines():
    return Lines(), DirectSolver()


def _options():
    return unit_search_options(max_points=200, ds_max=0.1)


def _interrupted(partial, seeds):
    def stop(i, fb):
        partial.branch("dlft", i, fb, 1)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        search(lines, seeds, [], _options(), on_corrections=lambda c: partial.corrections("dlft", c, seeds),
               on_branch=stop)


def test_a_resume_with_the_same_seeds_keeps_what_was_done(tmp_path):
    partial = _Partial(tmp_path / "isolas.partial.h5", "h")
    seeds = [Seed(0.5, np.array([-0.1]), "modal"), Seed(0.3, np.array([1.2]), "modal")]
    _interrupted(partial, seeds)
    c, done = partial.resume("dlft", seeds)
    assert c is not None and len(done) == 1
    res = search(lines, seeds, [], _options(), corrections=c, branches=done)
    assert res.n_continued == 1  # only the second line
    for b, line in zip(res.branches, (0.0, 1.0)):
        np.testing.assert_allclose(b.x[:, 0], line, atol=1e-12)


def test_a_resume_with_other_seeds_starts_over(tmp_path):
    partial = _Partial(tmp_path / "isolas.partial.h5", "h")
    seeds = [Seed(0.5, np.array([-0.1]), "modal")]
    _interrupted(partial, seeds)
    more = seeds + [Seed(0.3, np.array([1.2]), "ti class 1 period 2")]  # the sweep's seed, new
    c, done = partial.resume("dlft", more)
    assert c is None and done == []
    res = search(lines, more, [], _options(), corrections=c, branches=done)
    assert list(res.seed_branch) == [0, 1] and res.n_continued == 2
    for b, line in zip(res.branches, (0.0, 1.0)):
        np.testing.assert_allclose(b.x[:, 0], line, atol=1e-12)
        assert b.omega.min() == 0.0 and b.omega.max() == 1.0
    # the same number of seeds, another start guess (a sweep computed again): starts over too
    moved = [seeds[0], Seed(0.3, np.array([1.3]), "ti class 1 period 2")]
    partial2 = _Partial(tmp_path / "b.partial.h5", "h")
    _interrupted(partial2, more)
    assert partial2.resume("dlft", moved) == (None, [])
    assert partial2.resume("dlft", more)[0] is not None
