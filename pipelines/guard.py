"""Before a run computes: will it fit? And after meshing: is the blade the size of a blade?

check_run prints each planned stage's estimate (what drives its size, memory, time, disk;
pipelines.stages.base.Estimate) and refuses, in one line naming the scene key to change,
a stage whose memory exceeds this machine's (or [limits] memory_gb), a stage whose
temporary files exceed the free space of TMPDIR (e.g. the out-of-core Cholesky factor), or a
run whose files exceed the free space of the output folder. --yes runs it anyway.

blade_warnings checks a meshed blade against what turbomachine blades are, in the unit the
scene said its table is in: a table in feet read as metres gives a rotor-67 tip moving at
1700 m/s at 2000 rad/s, which no blade survives.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from pipelines.errors import FolderError, Refused

#: Largest tip speed of any turbomachine blade, m/s: transonic fans and compressors reach
#: 450-550 m/s (rotor 67: 429 m/s at design), high-pressure turbines ~500-600 m/s; above
#: ~700 m/s the centrifugal stress exceeds what titanium or nickel alloys bear.
MAX_TIP_SPEED = 700.0
#: Tip radius of turbomachine blades, m: from micro gas turbines (~1 cm) to the largest
#: turbofan fans (GE9X: 1.7 m) and large steam-turbine last stages (~2.5 m).
TIP_RADIUS = (0.005, 3.0)
#: Span (hub to tip) of a blade, m: ~2 mm (micro turbines) to ~1.5 m (steam last stages).
SPAN = (0.002, 1.5)


def machine_memory() -> int:
    """Physical memory of this machine, bytes."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def gb(n: float) -> str:
    """A size in bytes, in words."""
    for unit, k in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= k:
            return f"{n / k:.3g} {unit}"
    return f"{n:.0f} B"


def count(n: float) -> str:
    """A count for people: 24 104, 1.1e+14."""
    return f"{n:,.0f}".replace(",", " ") if n < 1e7 else f"{n:.2g}"


def duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.2g} days"


def memory_limit(scene) -> float:
    """The memory a run may use, bytes: [limits] memory_gb, else this machine's."""
    return scene.limits.memory_gb * 1e9 if scene.limits.memory_gb > 0 else machine_memory()


def check_run(scene, out: Path, steps, progress, yes: bool = False, disk: float = 0.0) -> float:
    """Estimate each stage of the plan that computes; refuse what cannot fit (unless yes).
    disk: bytes already planned by an earlier call for this run. Returns the bytes planned."""
    limit = memory_limit(scene)
    biggest = None
    for s in steps:
        if not s.todo:
            continue
        est = s.stage.estimate(scene, out, s.todo)
        if est is None:
            continue
        progress.log(f"[{s.stage.name}] estimate: {est.size}; memory ~{gb(est.memory)}, time ~{duration(est.seconds)}, "
                     f"files ~{gb(est.disk)}" + (f", temporary files ~{gb(est.scratch)}" if est.scratch else ""))
        if est.memory > limit and not yes:
            where = "[limits] memory_gb" if scene.limits.memory_gb > 0 else "this machine's memory"
            raise Refused(f"[{s.stage.name}] {est.size} would need ~{gb(est.memory)} of memory, more than {where} "
                          f"({gb(limit)}): {est.advice}; or pass --yes (or raise [limits] memory_gb) to run it anyway")
        if est.scratch > 0:
            tmp = tempfile.gettempdir()
            tmp_free = shutil.disk_usage(tmp).free
            if est.scratch > tmp_free and not yes:
                other = f", or {est.scratch_advice}" if est.scratch_advice else ""
                raise FolderError(f"[{s.stage.name}] {est.size} writes ~{gb(est.scratch)} of temporary files "
                                  f"({est.scratch_what}) under {tmp}, which has {gb(tmp_free)} free: "
                                  f"point TMPDIR to a larger disk{other} (--yes runs it anyway)")
        disk += est.disk
        if biggest is None or est.disk > biggest[1]:
            biggest = (s.stage.name, est.disk)
    if biggest is None:
        return disk
    free = shutil.disk_usage(out).free
    if disk > free and not yes:
        raise FolderError(f"not enough free space in {out}: this run writes ~{gb(disk)} (stage {biggest[0]}: "
                          f"~{gb(biggest[1])}), {gb(free)} free; free some space or give another --out "
                          "(--yes runs it anyway)")
    return disk


def blade_warnings(scene, nodes: np.ndarray, unit: str | None = None) -> list[str]:
    """Warnings when the meshed blade (nodes (n, 3), m, z the rotation axis) is implausible
    for a turbomachine blade read in `unit` (a KNOWN_UNITS key; None: [blade] units; a
    table read without it is in the unit the table states)."""
    r = np.hypot(nodes[:, 0], nodes[:, 1])
    tip, span = float(r.max()), float(r.max() - r.min())
    omega = max(scene.hbm.omega_max, scene.ti.omega_max)
    unit = scene.blade.units if unit is None else unit
    problems = []
    if tip * omega > MAX_TIP_SPEED:
        problems.append(f"at {omega:g} rad/s its tip would move at {tip * omega:.0f} m/s, beyond any "
                        f"turbomachine blade (< {MAX_TIP_SPEED:.0f} m/s)")
    if not TIP_RADIUS[0] <= tip <= TIP_RADIUS[1]:
        problems.append(f"a tip radius outside {TIP_RADIUS[0]:g}-{TIP_RADIUS[1]:g} m")
    if not SPAN[0] <= span <= SPAN[1]:
        problems.append(f"a span outside {SPAN[0]:g}-{SPAN[1]:g} m")
    if not problems:
        return []
    from mesh.options import KNOWN_UNITS

    scale = KNOWN_UNITS.get(unit, 1.0)
    fits = [u for u, k in KNOWN_UNITS.items() if u != unit
            and TIP_RADIUS[0] <= tip * k / scale <= TIP_RADIUS[1] and SPAN[0] <= span * k / scale <= SPAN[1]
            and tip * k / scale * omega <= MAX_TIP_SPEED]
    hint = (" Read in " + " or ".join(f"{u} it would have a tip radius of {tip * KNOWN_UNITS[u] / scale:.3g} m"
                                     for u in fits) + "." if fits else "")
    said = f"[blade] units = \"{unit}\"" if scene.blade.units is not None else "the unit the table states"
    return [f"the blade read in {unit} ({said}) has a tip radius of {tip:.3g} m and a span of "
            f"{span:.3g} m: " + "; ".join(problems) + f". Is the table in another unit?{hint}"]
