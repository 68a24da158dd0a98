#!/usr/bin/env python3
"""Print sanity statistics of a generated set (targets vs achieved ratios,
output ranges, clipping, saturation repeatability in the id sweep)."""
import glob
import json
import os
import sys

import numpy as np


def load(path):
    d = np.loadtxt(path, delimiter=",", skiprows=4)
    return d[:, 0], d[:, 1], d[:, 2]


def main(out):
    for tf in sorted(glob.glob(os.path.join(out, "truth", "case_*.json"))):
        T = json.load(open(tf))
        c = T["case"]
        t, u, y = load(os.path.join(out, c, "id.csv"))
        top = np.abs(u - 10.0) < 1e-9
        ytop = y[top]
        bot = np.abs(u + 10.0) < 1e-9
        forms = ",".join("%s(tg %.1f got %.1f)" % (f["form"], f["target_ratio"],
                         f["ratio_experiments_alone"]) for f in T["forms"]) or "-"
        nfiles = len(T["files"])
        clip = sum(T["clipped_samples_per_file"].values())
        print("%s %-26s files=%d rise=%4.1fms sigma=%.2fmV ratio_exp=%6.2f | id y@+10: %.3f..%.3f"
              " y@-10: %s | yrange %.2f..%.2f clip=%d | %s" % (
                  c, "+".join(T["kinds"]), nfiles, T["step_rise_ms"], 1e3 * T["noise_rms"],
                  T["ratio_experiments"], ytop.min(), ytop.max(),
                  "%.3f" % y[bot].min() if bot.any() else "n/a",
                  y.min(), y.max(), clip, forms))


if __name__ == "__main__":
    main(sys.argv[1])
