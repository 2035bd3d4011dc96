#!/usr/bin/env python3
"""Flash by symbol between two firmware images: what grew, what shrank.

    python3 tools/symdiff.py OLD.elf NEW.elf

Sums the sizes of the text and read-only symbols of each image (`llvm-nm --size-sort -S
--demangle`, from rustup's llvm-tools), merged by name without the hash, and prints every
symbol whose size changed, smallest change first, and the total. The images are
`target/thumbv7em-none-eabihf/firmware/firmware` of two builds (`cargo xtask build-fw`;
build the old one in a `git worktree`)."""
import collections
import pathlib
import re
import subprocess
import sys


def llvm_nm() -> str:
    found = sorted(pathlib.Path.home().glob(".rustup/toolchains/*/lib/rustlib/*/bin/llvm-nm"))
    if not found:
        sys.exit("symdiff: llvm-nm not found (rustup component add llvm-tools)")
    return str(found[0])


def sizes(nm: str, elf: str) -> collections.Counter:
    out = subprocess.run([nm, "--size-sort", "-S", "--demangle", elf], capture_output=True, text=True, check=True)
    total = collections.Counter()
    for line in out.stdout.splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[2] in "tTrR":
            total[re.sub(r"::h[0-9a-f]{16}$", "", parts[3])] += int(parts[1], 16)
    return total


def main() -> None:
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    nm = llvm_nm()
    old, new = sizes(nm, sys.argv[1]), sizes(nm, sys.argv[2])
    for delta, name in sorted((new[k] - old[k], k) for k in set(old) | set(new) if new[k] != old[k]):
        print(f"{delta:+6d} {old[name]:6d} {new[name]:6d} {name[:110]}")
    print("total", sum(new.values()) - sum(old.values()))


if __name__ == "__main__":
    main()
