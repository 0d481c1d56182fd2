#!/usr/bin/env python3
"""Can a lone return above a crown be told from the crown's own top?

usage: tools/top_return_gaps.py [--silva BIN] [--work DIR] [--seeds A B]
                                [--scan als|tls] [SYNTH_ARGS ...] [-- CLOUD ...]

The isolated-group rule (`reconstruct::ISOLATED_GROUPS`) drops returns with
no other within 3 m; a lone return nearer than that above the crown (a
bird) sets the tree's height. A test on the heights alone would be a
Dixon-type ratio: with z₁ ≥ z₂ ≥ … the heights of the highest returns,
u = (z₁ − z₂) / (z₂ − z_K), the gap under the highest over the spread of
the next K − 1 (K = 20, the dome's count in `metrics::apex_gap`). Under
apex_gap's dome model (returns' depths below the apex a Poisson process of
intensity ∝ d) its tail is P(u > 1.80) = 1e-5 (Monte Carlo, `--model`).

For every species and seed in range this prints, per species, the largest
u over the synthetic clips (`silva synth --species S --seed N --scan SCAN
SYNTH_ARGS -o ...`), its 99th percentile, and the median height above the
highest return from which a return would pass 1.80 (1.80 × (z₁ − z₁₉)),
then u for each CLOUD given after `--`. Needs numpy.
"""
import argparse
import os
import subprocess

import numpy as np

K = 20
SPECIES = ("oak", "birch", "poplar", "pine")


def ratio(z, k=K):
    """u of the highest returns of heights `z`."""
    z = np.sort(z)[::-1][:k]
    return (z[0] - z[1]) / max(z[1] - z[k - 1], 1e-9)


def reach(z, threshold):
    """Height above the highest return from which a lone return passes."""
    z = np.sort(z)[::-1]
    return threshold * (z[0] - z[K - 2])


def model_tail(draws=5_000_000, chunk=500_000, seed=1):
    """The 1e-3 to 1e-6 quantiles of u under the dome model."""
    rng = np.random.default_rng(seed)
    u = []
    for _ in range(draws // chunk):
        t = np.sqrt(rng.exponential(size=(chunk, K)).cumsum(1))
        u.append((t[:, 1] - t[:, 0]) / (t[:, K - 1] - t[:, 1]))
    u = np.concatenate(u)
    return {q: float(np.quantile(u, 1 - q)) for q in (1e-3, 1e-4, 1e-5, 1e-6)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--silva", default="target/release/silva")
    ap.add_argument("--work", default="/tmp/top_return_gaps")
    ap.add_argument("--seeds", nargs=2, type=int, default=(1, 151))
    ap.add_argument("--scan", default="als")
    ap.add_argument("--threshold", type=float, default=1.80)
    ap.add_argument("--model", action="store_true", help="print the model's tail first")
    args, rest = ap.parse_known_args()
    synth_args, clouds = (rest[: rest.index("--")], rest[rest.index("--") + 1:]) if "--" in rest else (rest, [])
    if args.model:
        print("dome model, tail probability: u", model_tail())
    os.makedirs(args.work, exist_ok=True)
    tag = "_".join([args.scan, *synth_args]).replace("-", "")
    for species in SPECIES:
        us, reaches = [], []
        for seed in range(*args.seeds):
            path = os.path.join(args.work, f"{species}{seed}-{tag}.xyz")
            if not os.path.exists(path):
                subprocess.run([args.silva, "synth", "--species", species, "--seed", str(seed),
                                "--scan", args.scan, *synth_args, "-o", path],
                               check=True, capture_output=True)
            z = np.loadtxt(path, usecols=(2,))
            us.append(ratio(z))
            reaches.append(reach(z, args.threshold))
        print(f"{species:7s} {len(us)} clips: u max {max(us):.3f}, 99th percentile "
              f"{np.percentile(us, 99):.3f}; a lone return passes from a median "
              f"{np.median(reaches):.2f} m above the highest")
    for cloud in clouds:
        print(f"{cloud}: u {ratio(np.loadtxt(cloud, usecols=(2,))):.3f}")


if __name__ == "__main__":
    main()
