#!/usr/bin/env python3
"""Where the Cortex-M4F's instructions go inside one function of a target program: an
executed-instruction profile under QEMU, attributed to source lines through the debug info.

    python3 tools/qemu_profile.py [--skip N] [--calls N] [--annotate | --whole | --longest K] [ELF] [SYMBOL | 0xADDR]

Defaults: `qemu-target/target/thumbv7em-none-eabihf/firmware/cost` (build it first:
`cd qemu-target && cargo build --target thumbv7em-none-eabihf --profile firmware --bin cost`,
the shipped profile) and `Drive::step` (the control interrupt's body; the slow step is a
function of its own, so this is the fast step with whatever is inlined into it).

Runs the program on `mps2-an386` one instruction per translation block (`-singlestep`),
logging only the executions inside SYMBOL's address range (`-d exec,nochain -dfilter`),
counts each address, drops the first `--skip` calls (the cost program's drive magnetizes
first, in the periods it prints as `cost magnetizing_periods`: not the Running step it
measures; a first plain run reads the count) and stops after `--calls` more. Calls are counted at SYMBOL's first instruction. Each address is mapped
with `llvm-addr2line -i` and its count charged to (a) the innermost function the compiler
inlined there and (b) the line of SYMBOL's own body (or of the function inlined into it
that the fast step calls, `Drive::fast_step`) it belongs to. Prints instructions per call.
A function that shares its name with others (closures) is named by its start address
(`0x…`, from `llvm-nm -C`).

It counts instructions inside the range only: out-of-line callees (the slow step, the
`#[inline(never)]` checks) are not in it, nor is what the caller does around the call
(ADC scaling, compare values) — `cost`'s `fast_step` figure is the whole period less a
tenth of the slow step. QEMU single-steps the whole program: ≈ 10 s for the cost program's
6 857 calls on this machine. Needs qemu-system-arm, llvm-nm, llvm-addr2line;
not run by CI.
"""
import argparse
import bisect
import collections
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_ELF = ROOT / "qemu-target/target/thumbv7em-none-eabihf/firmware/cost"
HASH = re.compile(r"::h[0-9a-f]{16}$")


def symbol_range(elf: Path, symbol: str) -> tuple[int, int]:
    """Start and size of the one function whose demangled name ends with `symbol`, or that
    starts at address `symbol` (`0x…`: closures share one name)."""
    if symbol.startswith("0x"):
        at = int(symbol, 16) & ~1
        hits = [(start, size, name) for start, size, name in functions(elf) if start == at]
    else:
        hits = [(start, size, name) for start, size, name in functions(elf) if name.endswith(symbol)]
    if len(hits) != 1:
        sys.exit(f"qemu_profile: {len(hits)} functions match {symbol!r}: {[h[2] for h in hits]}")
    return hits[0][0], hits[0][1]


def text_range(elf: Path) -> tuple[int, int]:
    """Start and size of the program's `.text` section."""
    out = subprocess.run(["llvm-size", "-A", "-x", str(elf)], check=True, capture_output=True, text=True).stdout
    for line in out.splitlines():
        parts = line.split()
        if parts and parts[0] == ".text":
            return int(parts[2], 16), int(parts[1], 16)
    sys.exit(f"qemu_profile: no .text in {elf}")


def functions(elf: Path) -> list[tuple[int, int, str]]:
    """Every function symbol: start, size, demangled name (hash removed)."""
    out = subprocess.run(["llvm-nm", "-S", "-C", str(elf)], check=True, capture_output=True, text=True).stdout
    fns = []
    for line in out.splitlines():
        parts = line.split(maxsplit=3)
        if len(parts) == 4 and parts[2] in "tT":
            fns.append((int(parts[0], 16) & ~1, int(parts[1], 16), HASH.sub("", parts[3])))
    return sorted(fns)


def profile(elf: Path, start: int, size: int, skip: int, calls: int, entry: int | None = None
            ) -> tuple[collections.Counter, int]:
    """Executions per address over `calls` calls after the first `skip`; with `entry`, every
    address in the range is logged and calls are counted at `entry`: the counts then cover
    `calls - 1` whole periods from one call's entry to the next's (callees and the caller's
    own work included)."""
    whole = entry is not None
    entry = start if entry is None else entry
    with tempfile.TemporaryDirectory() as tmp:
        fifo = Path(tmp) / "exec.log"
        subprocess.run(["mkfifo", str(fifo)], check=True)
        qemu = subprocess.Popen(
            ["qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic",
             "-semihosting-config", "enable=on,target=native", "-singlestep",
             "-d", "exec,nochain", "-dfilter", f"{start:#x}+{size:#x}", "-D", str(fifo),
             "-kernel", str(elf)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        counts: collections.Counter = collections.Counter()
        seen = 0
        pc = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/")
        try:
            with open(fifo) as log:
                for line in log:
                    m = pc.search(line)
                    if not m:
                        continue
                    addr = int(m.group(1), 16)
                    if addr == entry:
                        seen += 1
                        if seen > skip + calls or (whole and seen == skip + calls):
                            break
                        if seen % 500 == 0:
                            print(f"qemu_profile: {seen} calls", file=sys.stderr)
                    if seen > skip:
                        counts[addr] += 1
        finally:
            qemu.kill()
            qemu.wait()
        done = max(0, min(seen, skip + calls) - skip - (1 if whole else 0))
        if done == 0:
            sys.exit(f"qemu_profile: no call after the first {skip} (the program made {seen})")
        return counts, done


def call_sites(elf: Path, start: int) -> set[int]:
    """The return addresses of every `bl` to `start` in the program (a Thumb-2 `bl` is four
    bytes): where a call of the function ends."""
    out = subprocess.run(["llvm-objdump", "-d", "--no-show-raw-insn", str(elf)],
                         check=True, capture_output=True, text=True).stdout
    bl = re.compile(rf"^\s*([0-9a-f]+):\s*bl\s+0x{start:x}\b")
    return {int(m.group(1), 16) + 4 for m in map(bl.match, out.splitlines()) if m}


def calls_apart(elf: Path, start: int, ends: set[int], skip: int, calls: int
                ) -> list[collections.Counter]:
    """Each call of the function at `start` after the first `skip`, up to `calls` of them,
    whole — from its entry to its return to a call site (`ends`), callees included — as
    executions per address."""
    t0, tsize = text_range(elf)
    with tempfile.TemporaryDirectory() as tmp:
        fifo = Path(tmp) / "exec.log"
        subprocess.run(["mkfifo", str(fifo)], check=True)
        qemu = subprocess.Popen(
            ["qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic",
             "-semihosting-config", "enable=on,target=native", "-singlestep",
             "-d", "exec,nochain", "-dfilter", f"{t0:#x}+{tsize:#x}", "-D", str(fifo),
             "-kernel", str(elf)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        out: list[collections.Counter] = []
        seen, inside = 0, None
        pc = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/")
        try:
            with open(fifo) as log:
                for line in log:
                    m = pc.search(line)
                    if not m:
                        continue
                    addr = int(m.group(1), 16)
                    if inside is None:
                        if addr == start:
                            seen += 1
                            if seen > skip + calls:
                                break
                            if seen % 500 == 0:
                                print(f"qemu_profile: {seen} calls", file=sys.stderr)
                            inside = collections.Counter() if seen > skip else False
                    elif addr in ends:
                        if isinstance(inside, collections.Counter):
                            out.append(inside)
                        inside = None
                        continue
                    if isinstance(inside, collections.Counter):
                        inside[addr] += 1
        finally:
            qemu.kill()
            qemu.wait()
        if not out:
            sys.exit(f"qemu_profile: no whole call after the first {skip} (the program made {seen})")
        return out


def by_function(fns: list[tuple[int, int, str]], counts: collections.Counter) -> collections.Counter:
    """Executions per address charged to the out-of-line function holding the address."""
    starts = [f[0] for f in fns]
    per_fn: collections.Counter = collections.Counter()
    for addr, c in counts.items():
        k = bisect.bisect_right(starts, addr) - 1
        f0, fsize, name = fns[k] if k >= 0 else (0, 0, "?")
        per_fn[name if f0 <= addr < f0 + max(fsize, 1) else "?"] += c
    return per_fn


def attribute(elf: Path, counts: collections.Counter, outer: tuple[str, ...]):
    addrs = sorted(counts)
    out = subprocess.run(["llvm-addr2line", "-e", str(elf), "-f", "-C", "-i", "-a"],
                         input="".join(f"{a:#x}\n" for a in addrs), check=True,
                         capture_output=True, text=True).stdout
    inner: collections.Counter = collections.Counter()
    lines: collections.Counter = collections.Counter()
    for block in out.split("0x")[1:]:
        rows = block.strip().split("\n")
        addr = int(rows[0], 16)
        frames = [(HASH.sub("", rows[i]), rows[i + 1].split("/src/")[-1]) for i in range(1, len(rows) - 1, 2)]
        c = counts.get(addr, 0)
        inner[frames[0][0]] += c
        for fn, loc in frames:
            if fn.endswith(outer):
                lines[f"{fn.split('::')[-1]} {loc}"] += c
                break
        else:
            lines[f"{frames[-1][0]} {frames[-1][1]}"] += c
    return inner, lines


def magnetizing_periods(elf: Path) -> int:
    """The cost program's own count of the periods it magnetizes in (it prints it)."""
    out = subprocess.run(["qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic",
                          "-semihosting-config", "enable=on,target=native", "-icount", "shift=0",
                          "-kernel", str(elf)], capture_output=True, text=True, timeout=600).stdout
    m = re.search(r"^cost magnetizing_periods (\d+)$", out, re.M)
    if not m:
        sys.exit("qemu_profile: the program printed no `cost magnetizing_periods`: pass --skip")
    return int(m.group(1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("elf", nargs="?", default=str(DEFAULT_ELF))
    ap.add_argument("symbol", nargs="?", default="Drive::step")
    ap.add_argument("--skip", type=int, default=None,
                    help="calls to leave out first (default: the cost program's magnetizing periods, "
                         "read from its `cost magnetizing_periods` line in a first, plain run)")
    ap.add_argument("--calls", type=int, default=4096, help="calls to count (the cost program then runs 4 096 periods)")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--annotate", action="store_true",
                    help="also print SYMBOL's executed instructions in address order, each with its executions per call")
    ap.add_argument("--longest", type=int, metavar="K",
                    help="each call whole (entry to its return, callees included): the distribution of "
                         "instructions per call, and the K longest calls and a median one by function")
    ap.add_argument("--whole", action="store_true",
                    help="count every instruction from one call's entry to the next (callees, the caller's loop), by function")
    a = ap.parse_args()
    elf = Path(a.elf)
    if not elf.exists():
        sys.exit(f"qemu_profile: {elf} not found (build it first: see the module docs)")
    with open(elf, "rb") as f:
        if f.read(5) != b"\x7fELF\x01":
            sys.exit(f"qemu_profile: {elf} is not a 32-bit ELF program (the Cortex-M `cost` build)")
    start, size = symbol_range(elf, a.symbol)
    if a.skip is None:
        a.skip = magnetizing_periods(elf)
    if a.longest is not None:
        ends = call_sites(elf, start)
        if not ends:
            sys.exit(f"qemu_profile: no `bl` to {a.symbol} in {elf}: inlined everywhere")
        each = calls_apart(elf, start, ends, a.skip, a.calls)
        totals = sorted((sum(c.values()), i) for i, c in enumerate(each))
        q = lambda f: totals[min(len(totals) - 1, int(f * len(totals)))][0]
        print(f"{a.symbol}: {len(each)} whole calls after {a.skip}; instructions per call: "
              f"min {totals[0][0]}, median {q(0.5)}, 90 % {q(0.9)}, 99 % {q(0.99)}, max {totals[-1][0]}")
        fns = functions(elf)
        median = totals[len(totals) // 2]
        for total, i in [median] + totals[::-1][:a.longest]:
            what = "median" if (total, i) == median else "longest"
            print(f"\ncall {a.skip + i + 1} ({what}): {total} instructions, by function (out of line):")
            for fn, c in by_function(fns, each[i]).most_common(a.top):
                print(f"{c:8d}  {fn}")
        return
    if a.whole:
        t0, tsize = text_range(elf)
        counts, calls = profile(elf, t0, tsize, a.skip, a.calls, entry=start)
        total = sum(counts.values())
        print(f"{a.symbol}: {calls} whole periods (entry to entry) after {a.skip}; "
              f"{total / calls:.1f} instructions per period")
        fns = functions(elf)
        per_fn: collections.Counter = collections.Counter()
        k = 0
        for addr in sorted(counts):
            while k + 1 < len(fns) and fns[k + 1][0] <= addr:
                k += 1
            f0, fsize, name = fns[k] if fns else (0, 0, "?")
            per_fn[name if f0 <= addr < f0 + max(fsize, 1) else "?"] += counts[addr]
        print("\nper period, by function (out of line):")
        for fn, c in per_fn.most_common(a.top):
            print(f"{c / calls:8.1f}  {fn}")
        return
    counts, calls = profile(elf, start, size, a.skip, a.calls)
    total = sum(counts.values())
    print(f"{a.symbol}: {size} B at {start:#x}; {calls} calls after {a.skip}; "
          f"{total / calls:.1f} instructions per call inside it")
    inner, lines = attribute(elf, counts, ("Drive::fast_step", "Drive::step"))
    print("\nper call, by the innermost (inlined) function:")
    for fn, c in inner.most_common(a.top):
        print(f"{c / calls:8.1f}  {fn}")
    print("\nper call, by the line of the step's own body:")
    for loc, c in lines.most_common(a.top):
        print(f"{c / calls:8.1f}  {loc}")
    if a.annotate:
        annotate(elf, start, size, counts, calls)


def annotate(elf: Path, start: int, size: int, counts: collections.Counter, calls: int) -> None:
    """SYMBOL's disassembly (llvm-objdump), the executed instructions only, each with its
    executions per call."""
    out = subprocess.run(["llvm-objdump", "-d", "--no-show-raw-insn", f"--start-address={start:#x}",
                          f"--stop-address={start + size:#x}", str(elf)],
                         check=True, capture_output=True, text=True).stdout
    print("\nexecuted instructions, per call:")
    insn = re.compile(r"^\s*([0-9a-f]+):\s*(.*)$")
    for line in out.splitlines():
        m = insn.match(line)
        if m and counts.get(int(m.group(1), 16)):
            print(f"{counts[int(m.group(1), 16)] / calls:8.2f}  {m.group(1)}  {m.group(2)}")


if __name__ == "__main__":
    main()
