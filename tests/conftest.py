import sys
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy  # noqa: F401  (loads BLAS before the first test, for _blas_threads_kept)
import pytest
from threadpoolctl import threadpool_info

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # tests/support.py (stand-in ROM, SHARED data folder)


def pytest_addoption(parser):
    parser.addoption("--heavy", action="store_true",
                     help="also run the tests marked heavy (the ~200 000-node default scene: minutes and GB)")


def pytest_collection_modifyitems(config, items):
    # heavy runs are benchmarks on CI's 2 cores (its test run stays under ~15 minutes);
    # they stay runnable as tests, on request
    if config.getoption("--heavy"):
        return

    skip = pytest.mark.skip(reason="heavy: the default scene's mesh -> ROM; run with --heavy")
    for item in items:
        if "heavy" in item.keywords:
            item.add_marker(skip)


def _blas_threads() -> dict:
    return {p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}


@pytest.fixture(autouse=True)
def _blas_threads_kept():
    """Every test leaves the BLAS thread count of its process as it found it. A limit that
    outlives its call changes the round-off of whatever the process computes next, so tests
    would pass or fail by the order they run in, which two pytest workers change. Libraries
    loaded during the test are not compared."""
    before = _blas_threads()
    yield
    after = _blas_threads()
    changed = {k: (v, after[k]) for k, v in before.items() if k in after and after[k] != v}
    assert not changed, f"BLAS threads changed by this test (before, after): {changed}"
