"""The validation stage (pipelines.stages.validation) on an NFRC file that holds no converged
point, as the hbm stage writes one whose start failed (no point at all, or the failed start
alone): every point of the treatment is "none" with the reason, and validation.h5 is written
and read back."""
from types import SimpleNamespace

import numpy as np
import pytest

import pipelines.stages.validation as stage
from hbm.continuation.branch import ContinuationPoint
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions, TimeIntegrationOptions, ValidationOptions
from hbm.ti.march import rom_modal_system
from pipelines import artifacts as art
from pipelines.branch_store import BranchStore
from pipelines.stages.hbm import EXTRA_UNITS
from support import standin_rom


@pytest.mark.parametrize("failed_start", [False, True])
def test_an_nfrc_without_converged_points_gives_no_points_and_the_file_is_written(tmp_path, failed_start):
    """No isolas.h5, an NFRC stored without stability (no bifurcation table): the primary point
    is none ("no converged point on the branch"), the isola point none (no isolas.h5), the
    period-doubling point none ("fewer than two converged points"). Before, the file without
    points stopped the stage on its missing le_amplitude, and the failed start on the
    stability computed along a branch without a converged point."""
    rom = standin_rom()
    hbm = HbmOptions(n_harmonics=4, n_time=32, methods=("dlft",))
    res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.0), hbm, method="dlft")
    store = BranchStore.create(tmp_path / "nfrc_dlft.h5", res.size, units=EXTRA_UNITS)
    if failed_start:
        store.append(ContinuationPoint(0, 1000.0, np.zeros(res.size), False, 1.0, 40, 0.0, 0.1),
                     {"le_amplitude": np.nan})
    store.finalize("no start point")
    ctx = SimpleNamespace(out=tmp_path, scene=SimpleNamespace(
        validation=ValidationOptions(n_candidates=4, n_scan=2), hbm=hbm, casing=CasingOptions(),
        contact=ContactOptions(mu=0.0), ti=TimeIntegrationOptions()))
    t = stage._treatment(ctx, rom, rom_modal_system(rom), "dlft", lambda text: None)
    a = stage.ValidationArtifact(isolas="absent", growth_tol=1.5, deviation_tol=0.6, cpu_time=0.0, dlft=t)
    art.write_artifact(tmp_path / stage.VALIDATION.file, a, stage="validation")
    back = stage.read_validation(tmp_path).dlft
    assert [p.found for p in (back.primary, back.isola, back.period_doubling)] == [False] * 3
    assert back.primary.reason == "no converged point on the branch"
    assert back.isola.reason.startswith("no isolas.h5 in the output folder")
    assert back.period_doubling.reason == "the NFRC: fewer than two converged points"
    assert not back.pd_branch.found and len(back.nfrc_stable) == 0
