#!/usr/bin/env python3
"""Where lavapipe's JIT-compiled kernels spend a command's time, by instruction.

llvmpipe writes no perf map, so `perf report` shows its kernels as bare
addresses. This runs the command once under `perf record` with
`GALLIVM_DEBUG=asm` (and the shader cache off, so every kernel is compiled and
printed in that same process), then places each printed function where every
sampled address in its span falls on one of its instruction starts, and
prints the functions by samples. `--function K` also prints the hottest
windows of function K's listing with the samples of each instruction.

    tools/jit_profile.py -- target/release/srug bench splat --gaussians 1000000 \\
        --sizes 704x192 --repeats 9 --sort-keys 10000 --floor-pairs 10000
    tools/jit_profile.py --reuse /tmp/jit_profile --function 3

Needs `perf` (linux-perf) and permission to sample the process. A function's
hints (divisions, square roots, calls, scalar float compares) help tell which
kernel it is; a texel fetch is a call to a small `sample` function of its own.
"""

import argparse
import bisect
import collections
import os
import re
import subprocess
import sys

INSTRUCTION = re.compile(r"\s*([0-9a-f]+):\t(\S+)")
FUNCTION = re.compile(r"^([A-Za-z_][A-Za-z_0-9.]*):$")


def functions(listing):
    """(name, first line, [offsets], [mnemonics]) of every printed function."""
    out, current = [], None
    for number, line in enumerate(listing, 1):
        m = FUNCTION.match(line)
        if m:
            current = (m.group(1), number, [], [])
            out.append(current)
            continue
        m = INSTRUCTION.match(line)
        if m and current is not None:
            offset = int(m.group(1), 16)
            # A listing restarts at 0 for a function's own helpers; keep the first run.
            if current[2] and offset <= current[2][-1]:
                current = None
                continue
            current[2].append(offset)
            current[3].append(m.group(2))
    return [f for f in out if len(f[2]) >= 64]


def place(offsets, samples, ips, cumulative, anchors):
    """(base address, samples) where nearly every sample in the function's span
    lands on an instruction start, or None. Each anchor (a page's most sampled
    address) proposes the bases that would put it on one of the instructions;
    a wrong base fails within a sample or two (a random address is rarely an
    instruction start), so only the right one is checked through."""
    starts = set(offsets)
    size = offsets[-1] + 16
    best = None
    for anchor in anchors:
        for o in offsets:
            base = anchor - o
            lo, hi = bisect.bisect_left(ips, base), bisect.bisect_left(ips, base + size)
            total = cumulative[hi] - cumulative[lo]
            if total < 20 or (best is not None and total <= best[1]):
                continue
            allowed, missed = 0.03 * total, 0
            for ip in ips[lo:hi]:
                if ip - base not in starts:
                    missed += samples[ip]
                    if missed > allowed:
                        break
            else:
                best = (base, total - missed)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="/tmp/jit_profile", help="folder for perf.data and the listing")
    parser.add_argument("--reuse", metavar="DIR", help="analyse an earlier run's folder instead of running")
    parser.add_argument("--function", type=int, help="also show this function's hottest windows (its rank)")
    parser.add_argument("--window", type=int, default=40, help="instructions a window")
    parser.add_argument("--top", type=int, default=15, help="functions (and windows) to show")
    parser.add_argument("command", nargs="*", help="the command to profile, after --")
    args = parser.parse_args()

    folder = args.reuse or args.out
    data, listing_path = os.path.join(folder, "perf.data"), os.path.join(folder, "listing.txt")
    if not args.reuse:
        if not args.command:
            parser.error("give a command after -- (or --reuse DIR)")
        os.makedirs(folder, exist_ok=True)
        env = dict(os.environ, MESA_SHADER_CACHE_DISABLE="true", GALLIVM_DEBUG="asm")
        with open(listing_path, "w") as listing:
            run = subprocess.run(["perf", "record", "-F", "4000", "-o", data, "--", *args.command],
                                 stdout=listing, stderr=subprocess.STDOUT, env=env)
        if run.returncode != 0:
            sys.exit(f"the command failed ({run.returncode}); its output is in {listing_path}")

    script = subprocess.run(["perf", "script", "-i", data, "-F", "ip,dso"], capture_output=True, text=True)
    if script.returncode != 0:
        sys.exit(f"perf script failed: {script.stderr.strip()}")
    samples = collections.Counter()
    all_samples = 0
    for line in script.stdout.splitlines():
        parts = line.split()
        if len(parts) < 2:
            continue
        all_samples += 1
        if "perf-" in parts[1] or "JIT" in parts[1] or "unknown" in parts[1]:
            samples[int(parts[0], 16)] += 1
    jit_samples = sum(samples.values())
    # Each 4 KiB page's most sampled address anchors the search for the function holding it.
    by_page = {}
    for ip, _ in samples.most_common():
        by_page.setdefault(ip >> 12, ip)
    anchors = sorted(by_page.values())
    ips = sorted(samples)
    cumulative = [0]
    for ip in ips:
        cumulative.append(cumulative[-1] + samples[ip])
    with open(listing_path, errors="replace") as f:
        listing = f.read().splitlines()

    placed = []
    # Largest first; an anchor inside a placed function proposes no other.
    for name, line, offsets, mnemonics in sorted(functions(listing), key=lambda f: -len(f[2])):
        found = place(offsets, samples, ips, cumulative, anchors)
        if found:
            base, end = found[0], found[0] + offsets[-1] + 16
            anchors = [a for a in anchors if not base <= a < end]
            placed.append((found[1], found[0], name, line, offsets, mnemonics))
    placed.sort(reverse=True)
    print(f"{all_samples} samples, {jit_samples} in JIT code, "
          f"{sum(p[0] for p in placed)} placed in {len(placed)} functions")
    print("rank | samples | % of JIT | function | listing line | instructions | vdivps vsqrtps calls vucomiss")
    for rank, (n, base, name, line, offsets, mnemonics) in enumerate(placed[: args.top]):
        count = collections.Counter(mnemonics)
        hints = f"{count['vdivps']} {count['vsqrtps']} {count['callq']} {count['vucomiss']}"
        print(f"{rank} | {n} | {100 * n / max(jit_samples, 1):.1f} | {name} | {line} | {len(offsets)} | {hints}")

    if args.function is not None:
        if not 0 <= args.function < len(placed):
            sys.exit(f"--function {args.function}: only {len(placed)} functions placed")
        n, base, name, line, offsets, mnemonics = placed[args.function]
        per = collections.Counter()
        index = {o: k for k, o in enumerate(offsets)}
        for ip, c in samples.items():
            if ip - base in index:
                per[index[ip - base]] += c
        windows = collections.Counter()
        for k, c in per.items():
            windows[k // args.window] += c
        print(f"\nfunction {args.function} (listing line {line}): {n} samples; hottest windows of {args.window}")
        for w, c in windows.most_common(args.top):
            print(f"instructions {w * args.window}-{w * args.window + args.window - 1} "
                  f"(offset {offsets[w * args.window]:x}, listing line {line + 1 + w * args.window}): "
                  f"{c} samples, {100 * c / n:.1f}%")
        if windows:
            w = windows.most_common(1)[0][0]
            print("\nthe hottest window, samples per instruction:")
            for k in range(w * args.window, min(w * args.window + args.window, len(offsets))):
                print(f"{per[k]:6d}  {offsets[k]:6x}  {listing[line + k]}")


if __name__ == "__main__":
    main()
