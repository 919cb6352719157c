"""Where the lane kernel's time goes, by compiled function and by instruction class (Linux perf).

Usage (from the repository root, dev install; needs `perf` (Debian: linux-perf) with
/proc/sys/kernel/perf_event_paranoid <= 2, and objdump for the instruction mix):

    python benchmarks/profile_lanes.py                    # 6 Hz at gap 0 (every pair pounds), event
    python benchmarks/profile_lanes.py --gap 0.05         # no contact
    python benchmarks/profile_lanes.py --scheme implicit

The lane kernel is compiled into a temporary Numba cache (about 45 s), so that its linked LLVM
module is at hand: every compiled function's address goes into /tmp/perf-PID.map, where perf
finds the names of JIT code. Then `perf record -p` samples this process while it runs a 16-run
grid (bench_throughput section 7's) over and over, on one thread. Printed: the share of samples
per function, then the instruction mix of the hottest compiled function (samples by the class
of the instruction they landed on: on an out-of-order CPU a sample lands near, not on, the
instruction that stalled, so read classes, not single instructions).
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import llvmlite.binding as llvm

REPO = Path(__file__).resolve().parents[1]


def short(name: str) -> str:
    """`_ZN14pounding_sweep6engine5lanes6vector8_contactB3v51...` -> `engine.lanes.vector._contact` (a closure:
    `...6events15event_functions8<locals>12locate_event` -> `engine.events.event_functions.<locals>.locate_event`)."""
    at = name.find("14pounding_sweep")
    if at < 0:
        return name[:60]
    rest = name[at + len("14pounding_sweep") :]
    parts = []
    while rest and rest[0].isdigit() and len(parts) < 6:
        n = int(re.match(r"\d+", rest).group(0))
        k = len(str(n))
        parts.append(rest[k : k + n])
        rest = rest[k + n :]
    return ".".join(parts)


def compiled_functions(*dispatchers) -> tuple[list[tuple[int, str]], list[int]]:
    """(address, name) of every function defined in the dispatchers' linked modules, by address, and where each
    library's code ends (its first function's address plus its object's text size: the last function of a library
    ends there, not at the next library's first symbol, which can lie far on)."""
    out, ends = [], []
    for cres in (c for d in dispatchers for c in d.overloads.values()):
        lib = cres.library
        found = []
        for f in lib._final_module.functions:
            if f.is_declaration:
                continue
            try:
                addr = lib.get_pointer_to_function(f.name)
            except Exception:  # noqa: BLE001 (a name the engine did not export)
                continue
            if addr:
                found.append((addr, f.name))
        if found:
            # the object code Numba cached, else the final module's made again (numba core/codegen.py)
            buf = getattr(lib, "_compiled_object", None) or lib._codegen._tm.emit_object(lib._final_module)
            obj = llvm.ObjectFileRef.from_data(buf)
            text = sum(s.size() for s in obj.sections() if s.is_text())
            ends.append(min(found)[0] + text)
        out += found
    return sorted(set(out)), sorted(set(ends))


def function_end(syms: list, ends: list, k: int) -> int:
    """Where function k of syms ends: the next symbol, or its library's end (compiled_functions), whichever is
    first; at most MAX_FUNCTION_BYTES on."""
    addr = syms[k][0]
    nxt = syms[k + 1][0] if k + 1 < len(syms) else addr + MAX_FUNCTION_BYTES
    lib_end = min((e for e in ends if e > addr), default=nxt)
    return min(nxt, lib_end, addr + MAX_FUNCTION_BYTES)


#: the most bytes read as one function's code: its end is taken as the next symbol's address, which can lie
#: gigabytes on, in another mapping that is readable all the way (an implicit-scheme profile on a Zen 3 read for
#: ten minutes and held 19 GB); the largest compiled function here, the contact loop, is about 0.1 MiB
MAX_FUNCTION_BYTES = 4 << 20


def _mapped_bytes(addr: int, size: int) -> bytes:
    """Up to `size` bytes (at most MAX_FUNCTION_BYTES) of this process's memory from addr, stopping at the first
    unmapped page (the next symbol can lie in another module's mapping, so addr + size may run past this one's:
    reading that through a pointer crashed the process; /proc/self/mem answers EIO instead)."""
    size = min(size, MAX_FUNCTION_BYTES)
    out = bytearray()
    fd = os.open("/proc/self/mem", os.O_RDONLY)
    try:
        while len(out) < size:
            page_end = (addr + len(out)) // 4096 * 4096 + 4096
            want = min(size - len(out), page_end - (addr + len(out)))
            try:
                chunk = os.pread(fd, want, addr + len(out))
            except OSError:
                break
            if not chunk:
                break
            out += chunk
    finally:
        os.close(fd)
    return bytes(out)


def instruction_class(text: str) -> str:
    op = text.split()[0]
    ops = text[len(op) :].strip()
    mem = "(" in ops
    if op.startswith(("vmov", "vbroadcast", "mov")):
        return "store" if "(" in ops.split(",")[-1] else ("load" if mem else "register move")
    if op.startswith(("vfmadd", "vfnmadd", "vfmsub", "vfnmsub", "vmul")):
        return "multiply / FMA" + (" with a load" if mem else "")
    if op.startswith(("vadd", "vsub")):
        return "add / subtract" + (" with a load" if mem else "")
    if op.startswith(
        ("vcmp", "vblend", "vand", "vor", "vxor", "vpack", "vptest", "vmovmsk", "vperm", "vextract", "vinsert")
    ):
        return "compare / blend / mask" + (" with a load" if mem else "")
    return "scalar, branch, other"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gap", type=float, default=0.0, help="gap [m] of every run (0: every pair pounds)")
    ap.add_argument("--scheme", default="event", choices=["event", "implicit"])
    ap.add_argument("--seconds", type=float, default=4.0, help="how long perf samples")
    ap.add_argument(
        "--function", default="", help="the instruction mix of the hottest compiled function whose name has this"
    )
    ap.add_argument("--hot", type=int, default=0, help="also print its N instructions with the most samples")
    a = ap.parse_args()
    perf = shutil.which("perf")
    if perf is None:
        sys.exit("perf not found: install it (Debian: apt-get install linux-perf)")
    with open("/proc/sys/kernel/perf_event_paranoid") as f:
        if int(f.read()) > 2:
            sys.exit("perf_event_paranoid > 2: perf cannot sample this process")

    tmp = Path(tempfile.mkdtemp(prefix="profile_lanes_"))
    os.environ["NUMBA_CACHE_DIR"] = str(tmp / "cache")  # compile here: the linked module stays at hand
    pmap = Path(f"/tmp/perf-{os.getpid()}.map")
    try:
        _profile(a, perf, tmp, pmap)
    finally:
        pmap.unlink(missing_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)


def _profile(a, perf: str, tmp: Path, pmap: Path) -> None:
    """Compile, map, sample and print (main's work; main cleans up)."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    sys.argv = sys.argv[:1]
    import bench_throughput as B
    import numpy as np

    from pounding_sweep.engine import driver

    try:
        from pounding_sweep.engine.lanes.groups import _integrate_groups
    except ImportError:  # before engine/lanes became a package
        from pounding_sweep.engine.lanes import _integrate_groups

    s = B.scene(
        base=B.SCENE_6HZ,
        duration=2.0,
        scheme=a.scheme,
        sweep=[("gap_m", (a.gap,)), ("ks_ratio", np.geomspace(0.1, 10, 4)), ("r", np.linspace(0.2, 1, 4))],
    )
    prep = B.prepare(s)
    runs, rec = B.run_inputs(prep, points=prep.grid.size)
    t0 = time.perf_counter()
    driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, 1)
    print(f"compiled the lane kernel in {time.perf_counter() - t0:.0f} s")
    try:  # the vector loops of each pair of floor counts: libraries of their own, called by address
        from pounding_sweep.engine.lanes.loops import made_loops

        loops = made_loops()
    except ImportError:  # before engine/lanes/loops.py: linked into the driver
        loops = []
    syms, ends = compiled_functions(_integrate_groups, *loops)
    with open(pmap, "w") as fh:
        for k, (addr, name) in enumerate(syms):
            end = function_end(syms, ends, k)
            fh.write(f"{addr:x} {end - addr:x} {short(name)}\n")

    data = tmp / "perf.data"
    rec_p = subprocess.Popen(
        [perf, "record", "-q", "-p", str(os.getpid()), "-o", str(data)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    time.sleep(0.5)
    t0 = time.perf_counter()
    calls = 0
    while time.perf_counter() - t0 < a.seconds:
        driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, 1)
        calls += 1
    wall = time.perf_counter() - t0
    rec_p.send_signal(signal.SIGINT)
    rec_p.wait(timeout=60)
    steps = calls * runs.n * int(runs.nsteps.max())
    print(
        f"{calls} calls of the 16-run grid (gap {a.gap} m, {a.scheme} scheme), {wall:.1f} s: "
        f"{wall / steps * 1e9:.1f} ns per step and run on one thread, perf attached"
    )

    rep = subprocess.run(
        [perf, "report", "-i", str(data), "--stdio", "--sort", "symbol", "--percent-limit", "0.5"],
        capture_output=True,
        text=True,
    ).stdout
    shares = {m.group(2): float(m.group(1)) for m in re.finditer(r"([\d.]+)%\s+\[.\]\s+(\S+)", rep)}
    print("\nshare of samples   function")
    for fn, share in shares.items():
        print(f"{share:>15.2f}%   {fn}")

    named = [(shares.get(short(n), 0.0), k) for k, (_, n) in enumerate(syms) if a.function in short(n)]
    best, k = max(named, default=(0.0, 0))
    hot = syms[k]
    objdump = shutil.which("objdump")
    if objdump is None or best == 0.0:
        print("\n(no instruction mix: objdump missing or no samples in compiled code)")
        return
    addr, name = hot
    hot_name = short(name)
    end = function_end(syms, ends, k)
    binf = tmp / "hot.bin"
    binf.write_bytes(_mapped_bytes(addr, end - addr))
    asm = subprocess.run(
        [objdump, "-D", "-b", "binary", "-mi386:x86-64", f"--adjust-vma={addr:#x}", str(binf)],
        capture_output=True,
        text=True,
    ).stdout
    ips = collections.Counter()
    script = subprocess.run([perf, "script", "-i", str(data), "-F", "ip,sym"], capture_output=True, text=True).stdout
    for line in script.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[1] == hot_name:
            ips[int(parts[0], 16)] += 1
    total = sum(ips.values())
    by_class, static = collections.Counter(), collections.Counter()
    text = {}
    for line in asm.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(\S.*)", line)
        if m:
            text[int(m.group(1), 16)] = m.group(2)
            c = instruction_class(m.group(2))
            by_class[c] += ips.get(int(m.group(1), 16), 0)
            static[c] += 1
    frame = re.search(r"sub\s+\$0x([0-9a-f]+),%rsp", asm)
    print(
        f"\ninstruction mix of {hot_name} ({total} samples; stack frame "
        f"{int(frame.group(1), 16) if frame else 0:,} bytes; {len(binf.read_bytes()):,} bytes read as its code, up to "
        "the next symbol or its library's end)"
    )
    print("share of samples   class   (instructions of that class in the code)")
    for c, n in by_class.most_common():
        print(f"{n / max(total, 1):>16.1%}   {c}   ({static[c]})")
    if a.hot:
        print(f"\nits {a.hot} instructions with the most samples (address order)")
        for ip, n in sorted(ips.most_common(a.hot)):
            print(f"{n / max(total, 1):>7.1%}  {ip:#x}  {text.get(ip, '?')}")


if __name__ == "__main__":
    main()
