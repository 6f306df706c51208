import sys
from pathlib import Path

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
    import pytest

    skip = pytest.mark.skip(reason="heavy: the default scene's mesh -> ROM; run with --heavy")
    for item in items:
        if "heavy" in item.keywords:
            item.add_marker(skip)
