#!/usr/bin/env python3
"""Two terrestrial scans of trees whose crowns touch, as one cloud: what silva says.

usage: tools/tls_pairs.py [--silva BIN] [--work DIR] [--pairs N] [SYNTH OPTION ...]

Makes N pairs (default 40) of `silva synth --scan tls` clouds: pair k is
species k mod 4 with seed 1001 + 2k and species (k div 4) mod 4 with seed
1002 + 2k (oak, birch, poplar, pine), each standing at the origin. The
second tree is moved 2, 3, 4, 6 and 8 m along x, the two clouds are written
as one XYZ file, and `silva reconstruct` runs on it in `--mode auto`. Any
SYNTH OPTION (such as `--ground-radius 4`) goes to `silva synth`.

Per distance it counts the answers:
- `stems`: refused for standing on two stems (`SeveralStems`);
- `upside+stems`: refused as upside down, with the two-trees reading;
- `clusters`: refused as separate clusters (a gap between the crowns);
- `one tree`: reconstructed as one tree (with the pipeline that ran);
- `other`: any other error.

The pairs that become one tree, and other errors, are printed.

This measures the figures in the docs of the dense pipeline's
`check_one_stem`; run it with the binary of an earlier commit to compare.
Needs numpy.
"""

import argparse
import collections
import os
import subprocess

import numpy as np

SPECIES = ["oak", "birch", "poplar", "pine"]
DISTANCES_M = [2, 3, 4, 6, 8]


def synth(silva, species, seed, out, options):
    subprocess.run(
        [silva, "synth", "--species", species, "--seed", str(seed), "--scan", "tls",
         "-o", out, "--truth", out + ".truth.json", *options],
        capture_output=True, check=True)
    return np.loadtxt(out)


def answer(silva, cloud, work):
    run = subprocess.run(
        [silva, "reconstruct", cloud, "--skeleton", os.path.join(work, "skeleton.json")],
        capture_output=True, text=True)
    lines = run.stderr.strip().splitlines()
    last = lines[-1] if lines else ""
    if run.returncode == 0:
        mode = next((l.split()[2] for l in lines if l.startswith("silva: mode ")), "?")
        return f"one tree ({mode})", last
    if "stems" in last:
        return ("upside+stems" if "upside down" in last else "stems"), last
    if "separate clusters" in last:
        return "clusters", last
    return "other", last


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--silva", default="target/release/silva")
    parser.add_argument("--work", default="/tmp/silva-tls-pairs")
    parser.add_argument("--pairs", type=int, default=40)
    args, options = parser.parse_known_args()
    os.makedirs(args.work, exist_ok=True)
    counts = collections.defaultdict(collections.Counter)
    for k in range(args.pairs):
        first = synth(args.silva, SPECIES[k % 4], 1001 + 2 * k,
                      os.path.join(args.work, "a.xyz"), options)
        second = synth(args.silva, SPECIES[(k // 4) % 4], 1002 + 2 * k,
                       os.path.join(args.work, "b.xyz"), options)
        for d in DISTANCES_M:
            moved = second + np.array([d, 0.0, 0.0])
            cloud = os.path.join(args.work, "pair.xyz")
            np.savetxt(cloud, np.vstack([first, moved]), fmt="%.4f")
            kind, last = answer(args.silva, cloud, args.work)
            counts[d][kind] += 1
            if kind == "other" or kind.startswith("one tree"):
                print(f"pair {k} ({SPECIES[k % 4]}, {SPECIES[(k // 4) % 4]}) at {d} m: "
                      f"{kind}: {last[:200]}")
    for d in DISTANCES_M:
        print(f"{d} m apart: {dict(counts[d])}")


if __name__ == "__main__":
    main()
