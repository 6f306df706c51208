"""Time meshing of rotor 67 at the default (~200k nodes) and coarse (~24k nodes) settings.

Each setting runs in its own process so that peak memory (ru_maxrss) is per setting.
Usage: .venv/bin/python benchmarks/bench_mesh.py [path/to/rotor67geometry.dat] [--settings default,coarse]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_TABLE = ROOT.parent / "shared" / "data" / "rotor67" / "rotor67geometry.dat"
SETTINGS = {
    "default": {},
    "coarse": {"element_size": 0.008, "edge_layers": 1, "size_growth": 0.5},
}

CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, {root!r})
from pathlib import Path
from mesh.blade import mesh_blade
from mesh.options import BladeOptions, MeshOptions
opts = MeshOptions(**json.loads({kw!r}))
t0 = time.perf_counter()
m = mesh_blade(BladeOptions(), opts, Path({table!r}))
dt = time.perf_counter() - t0
print(json.dumps(dict(element_size=opts.element_size, edge_layers=opts.edge_layers,
    size_growth=opts.size_growth, nodes=m.n_nodes, cells=len(m.cells), root_facets=len(m.root_facets),
    tip_facets=len(m.tip_facets), volume=m.volume, reference_volume=m.reference_volume, seconds=dt,
    peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def main(table: Path = DEFAULT_TABLE, settings=tuple(SETTINGS)):
    for name in settings:
        kw = SETTINGS[name]
        code = CHILD.format(root=str(ROOT), kw=json.dumps(kw), table=str(table))
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        if out.returncode:  # say why: the child's output is captured
            raise SystemExit(f"{name}: meshing failed (exit {out.returncode}):\n{out.stderr.strip()}")
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"{name:8s} element_size={r['element_size']:.5f} m edge_layers={r['edge_layers']} "
              f"size_growth={r['size_growth']}: {r['nodes']} nodes, {r['cells']} tet10, "
              f"{r['root_facets']} root / {r['tip_facets']} tip tri6, volume {r['volume']:.4e} m^3 "
              f"(section integral {r['reference_volume']:.4e}), {r['seconds']:.1f} s, "
              f"peak RSS {r['peak_rss_mb']:.0f} MB")


def _settings(text: str) -> tuple[str, ...]:
    names = tuple(n for n in text.split(",") if n)
    unknown = [n for n in names if n not in SETTINGS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown setting(s) {unknown}; known: {', '.join(SETTINGS)}")
    return names


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("table", nargs="?", type=Path, default=DEFAULT_TABLE, help="rotor 67 geometry table")
    ap.add_argument("--settings", type=_settings, default=tuple(SETTINGS),
                    help="comma-separated among " + ", ".join(SETTINGS) + " (default: all)")
    a = ap.parse_args()
    main(a.table, a.settings)
