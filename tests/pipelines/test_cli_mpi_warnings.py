"""`mpirun -n 2 bladerub run ...`: rank 0 does all the talking, scene warnings included."""
import subprocess
import sys
from pathlib import Path

from support import mpirun_command, needs_mpirun

ROOT = Path(__file__).resolve().parents[2]
COARSE = ROOT / "scenes" / "rotor67_coarse.toml"


@needs_mpirun
def test_a_scene_warning_is_printed_once_under_mpirun(tmp_path):
    """Every rank printed the scene's warnings (`[casing] penetration = 0 m <= 0 ...` twice
    under `mpirun -n 2`). The size guard then refuses the run before anything is computed."""
    words, env = mpirun_command(ROOT)
    out = tmp_path / "out"
    proc = subprocess.run([*words, sys.executable, "-m", "pipelines.cli", "run", str(COARSE), "--out", str(out),
                           "--until", "mesh", "--quiet", "--set", "casing.penetration=0",
                           "--set", "mesh.edge_layers=100000"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.stderr.count("bladerub: warning: [casing] penetration = 0 m <= 0") == 1, proc.stderr
    assert proc.stderr.count("bladerub: error: [mesh] ") == 1, proc.stderr
    assert not (out / "mesh.h5").exists()
