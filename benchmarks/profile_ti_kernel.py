"""Where a march's time goes inside the compiled step loop, instruction by instruction.

    perf record -c 50000 -e cycles -o ti.data .venv/bin/python benchmarks/profile_ti_kernel.py \\
        --rom out/main/rom.h5 --omega 1000 --revolutions 200 --dump ti_code
    .venv/bin/python benchmarks/profile_ti_kernel.py --report ti.data --dump ti_code [--top 40]

numba's code has no symbols perf can read (and code loaded from numba's cache not even a
perf map), so the first command marches one speed (no early stop) under perf and then
writes the step loop's machine code and its load address (ti_code.bin, ti_code.addr); the
second maps perf's samples onto that code (objdump disassembles it) and prints the share of
samples per 128-byte stretch of code, then the hottest instructions. The stretches are
read against the kernel's source by their instructions (the prediction: the FMAs on ymm
accumulators; the casing test: vroundsd, the floor of the lobe coordinate). Needs perf and
objdump (Debian: linux-perf, binutils); pin the process (`taskset -c 1`) for steadier
figures.
"""
from __future__ import annotations

import argparse
import collections
import ctypes
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

#: Bytes of machine code dumped from the step loop's entry (its code is ~45 kB on rotor 67).
CODE_BYTES = 1 << 16


def march(a) -> None:
    """March one speed, then dump the step loop's code and address."""
    from bench_ti import load_rom
    from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions
    from hbm.ti import kernel
    from hbm.ti.march import rom_modal_system
    from hbm.ti.sweep import simulate

    rom, label = load_rom(a.rom)
    system = rom_modal_system(rom)
    cas, con = CasingOptions(), ContactOptions()
    simulate(system, cas, con.mu, 2000.0, TimeIntegrationOptions(n_revolutions=2, n_keep=1))  # compile or load
    t0 = time.process_time()
    r = simulate(system, cas, con.mu, a.omega, TimeIntegrationOptions(n_revolutions=a.revolutions,
                                                                      stop_when_settled=False))
    print(f"ROM {label}: {a.omega:g} rad/s, {a.revolutions} revolutions, {time.process_time() - t0:.2f} s CPU, "
          f"LE amplitude {r.amplitude:.6e} m, contact steps {r.contact_fraction:.2f}")
    (cres,) = kernel.run_steps.overloads.values()
    addr = cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)
    Path(f"{a.dump}.bin").write_bytes(ctypes.string_at(addr, CODE_BYTES))
    Path(f"{a.dump}.addr").write_text(str(addr))


def report(a) -> None:
    """Samples per stretch of the dumped code, and the hottest instructions."""
    addr = int(Path(f"{a.dump}.addr").read_text())
    ips = subprocess.run(["perf", "script", "-i", a.report, "-F", "ip"], capture_output=True, text=True,
                         check=True).stdout.split()
    hits = collections.Counter(int(ip, 16) - addr for ip in ips if 0 <= int(ip, 16) - addr < CODE_BYTES)
    asm = subprocess.run(["objdump", "-D", "-b", "binary", "-mi386:x86-64", "--no-show-raw-insn", f"{a.dump}.bin"],
                         capture_output=True, text=True, check=True).stdout
    text = {int(m.group(1), 16): m.group(2) for m in re.finditer(r"^\s*([0-9a-f]+):\s*(.*)$", asm, re.M)}
    total = sum(hits.values())
    print(f"{total} samples in the step loop, {len(ips)} in all\n\n| code offset | share |\n|---|---|")
    blocks = collections.Counter()
    for off, n in hits.items():
        blocks[off // 128] += n
    for b in sorted(blocks):
        if blocks[b] >= 0.01 * total:
            print(f"| {b * 128:#06x} | {100 * blocks[b] / total:.1f} % |")
    print("\n| offset | share | instruction |\n|---|---|---|")
    for off, n in sorted(sorted(hits.items(), key=lambda t: -t[1])[:a.top]):
        print(f"| {off:#06x} | {100 * n / total:.2f} % | `{text.get(off, '?')}` |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rom", default="standin")
    ap.add_argument("--omega", type=float, default=650.0)
    ap.add_argument("--revolutions", type=int, default=60)
    ap.add_argument("--dump", default="ti_code", help="stem of the code dump (.bin, .addr)")
    ap.add_argument("--report", help="perf data file: report instead of marching")
    ap.add_argument("--top", type=int, default=30)
    a = ap.parse_args()
    report(a) if a.report else march(a)


if __name__ == "__main__":
    main()
