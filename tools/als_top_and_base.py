#!/usr/bin/env python3
"""What an airborne clip's returns tell about the tree's apex and trunk base.

usage: tools/als_top_and_base.py [--silva BIN] [--work DIR] REPORT.json[:DENSITY] ...

Reads reports of `silva eval --synthetic N --scan als --repeat 1` (with
`--density DENSITY`, 20 if not given after the name, and any `--leaves`,
which the report names), remakes each tree's clip with `silva synth
--species S --seed N --scan als --leaves L --density D -o DIR/...` (the
same tree and returns, standing at the origin instead of the eval's
EPSG:28992 anchor; its highest return matches the report's to 0.02 m), and
asks two questions that the reconstruction answers by a model.

Apex (`reconstruct::metrics::apex_gap`): the true gap between the highest
return and the true top (the report's height minus its height error, less
the highest return its note names) against the estimated gap of the note,
per species: the correlation of the two, and of the true gap with the
depths below the highest return of the 2nd, 5th and 10th highest returns.
Then how many gaps come within 0.3 m of the truth with the estimate; with
κ·ρ^(−1/m), where ρ is the clip's returns per m², m the top's exponent and
κ the median of gap·ρ^(1/m) in the first report for the same crown top
(dome or columnar) and crown reading (bare twigs or foliage, from the
reconstruction's note): the dome model's expected gap with its density
taken from the survey instead of from the top's own returns; and with the
posterior mean of the estimate's model when its density c is the count of
returns within 1.5 m of the highest over 1.5^m instead of integrated out.

Base (`reconstruct::airborne::trunk`): for the trees whose trunk Eq. 4
placed (no column of stem returns, from the report's trunk note), how many
of a few candidate base positions lie within 0.5 m of the true base (the
origin): the reconstruction's (from the report), the mean, the median and
the convex hull's area centroid of the crown's returns (more than 1.5 m
above the ground), the mean of its lowest and of its highest tenth by
height, and its highest return.

Needs numpy and scipy.
"""
import argparse
import json
import os
import re
import subprocess

import numpy as np
from scipy.spatial import ConvexHull

NOTE = re.compile(r"highest return ([\d.]+) m plus ([\d.]+) m .* of a (\w+) top")


def trees(report, silva, work, density):
    """One dict per synthetic tree of `report`, with its clip's returns."""
    report = json.load(open(report))
    for t in report["trees"]:
        species, seed, _ = t["name"].split("-")
        seed = seed[1:]
        path = os.path.join(work, f"{species}{seed}-{report['leaves']}-{density}.xyz")
        if not os.path.exists(path):
            subprocess.run([silva, "synth", "--species", species, "--seed", seed, "--scan", "als",
                            "--leaves", report["leaves"], "--density", density, "-o", path],
                           check=True, capture_output=True)
        height = [n for n in t["notes"] if n.startswith("height:")][0]
        highest, gap, top = NOTE.search(height).groups()
        true_top = t["metrics"]["height_m"] - t["truth"]["height_error_m"]
        points = np.loadtxt(path)
        z = np.sort(points[:, 2])[::-1]
        half = np.abs(points[:, :2]).max()
        yield dict(species=species, points=points, depths=z[0] - z,
                   density=len(points) / (2 * half) ** 2,
                   bare=any("bare twigs" in n for n in t["notes"]),
                   true_gap=true_top - float(highest), gap=float(gap), top=top,
                   base_off=t["truth"]["trunk_base_offset_m"],
                   eq4="Eq. 4 (footprint" in [n for n in t["notes"] if n.startswith("trunk:")][0])


def fixed_density_gap(depths, m, window=1.5, k=20):
    """Posterior mean gap with c = returns within `window` / window^m."""
    c = (depths <= window).sum() / window**m
    s = depths[:k]
    g = np.linspace(0.0, 3.0, 600) + 1e-4
    log_l = ((m - 1) * np.log(g[:, None] + s[None, :])).sum(1) - c * (g + s[-1]) ** m
    w = np.exp(log_l - log_l.max())
    return (w * g).sum() / w.sum()


def exponent(top):
    """m of `CrownTop::exponent`: the volume above depth d grows as d^m."""
    return 1.5 if top == "columnar" else 2.0


def calibrate(rows):
    """κ per crown top and crown reading (bare twigs or foliage) such that
    the median true gap of `rows` is κ·ρ^(−1/m), ρ the clip's returns per
    m²: the dome model's scaling of the expected gap with density."""
    kappa = {}
    for key in {(r["top"], r["bare"]) for r in rows}:
        kappa[key] = np.median([r["true_gap"] * r["density"] ** (1 / exponent(key[0]))
                                for r in rows if (r["top"], r["bare"]) == key])
    return kappa


def apex(runs):
    kappa = calibrate(runs[0][1])
    print("== apex: κ calibrated on " + runs[0][0] + ": "
          + ", ".join(f"{t} {'bare' if b else 'foliage'} {k:.2f}" for (t, b), k in sorted(kappa.items())))
    for name, rows in runs:
        print(f"== apex, {name}")
        for species in sorted({r["species"] for r in rows}):
            sub = [r for r in rows if r["species"] == species]
            true = np.array([r["true_gap"] for r in sub])
            corr = lambda v: np.corrcoef(true, v)[0, 1]
            depth = ", ".join(f"return {k + 1} {corr([r['depths'][k] for r in sub]):+.2f}"
                              for k in (1, 4, 9))
            print(f"  {species:7s} true gap median {np.median(true):.2f} m, sd {true.std():.2f};"
                  f" correlation with the estimate {corr([r['gap'] for r in sub]):+.2f},"
                  f" with the depth of {depth}")
        true = np.array([r["true_gap"] for r in rows])
        within = lambda est: int((np.abs(np.array(est) - true) <= 0.3).sum())
        scaled = [kappa.get((r["top"], r["bare"]), np.nan) * r["density"] ** (-1 / exponent(r["top"]))
                  for r in rows]
        fixed = [fixed_density_gap(r["depths"], exponent(r["top"])) for r in rows]
        print(f"  within 0.3 m of the true gap, of {len(rows)}: estimate {within([r['gap'] for r in rows])},"
              f" κ·ρ^(−1/m) {within(scaled)}, density from 1.5 m {within(fixed)}")


def base(runs):
    for name, rows in runs:
        rows = [r for r in rows if r["eq4"]]
        counts = {k: 0 for k in ("reconstruction", "mean", "median", "hull centroid",
                                 "lowest tenth", "highest tenth", "highest return")}
        for r in rows:
            p = r["points"]
            crown = p[p[:, 2] > 1.5]
            z = crown[:, 2]
            hull = crown[ConvexHull(crown[:, :2]).vertices, :2]
            x, y = hull[:, 0], hull[:, 1]
            cross = x * np.roll(y, -1) - np.roll(x, -1) * y
            centroid = np.array([((x + np.roll(x, -1)) * cross).sum(),
                                 ((y + np.roll(y, -1)) * cross).sum()]) / (3 * cross.sum())
            spots = {
                "mean": crown[:, :2].mean(0),
                "median": np.median(crown[:, :2], 0),
                "hull centroid": centroid,
                "lowest tenth": crown[z <= np.quantile(z, 0.1), :2].mean(0),
                "highest tenth": crown[z >= np.quantile(z, 0.9), :2].mean(0),
                "highest return": crown[np.argmax(z), :2],
            }
            counts["reconstruction"] += r["base_off"] <= 0.5
            for k, xy in spots.items():
                counts[k] += np.linalg.norm(xy) <= 0.5
        print(f"== base, {name}: {len(rows)} trunks placed by Eq. 4; within 0.5 m of the true base:")
        print("  " + ", ".join(f"{k} {v}" for k, v in counts.items()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--silva", default="target/release/silva")
    ap.add_argument("--work", default="als-clips")
    ap.add_argument("reports", nargs="+")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    runs = []
    for arg in args.reports:
        report, _, density = arg.partition(":")
        runs.append((arg, list(trees(report, args.silva, args.work, density or "20"))))
    apex(runs)
    base(runs)


if __name__ == "__main__":
    main()
