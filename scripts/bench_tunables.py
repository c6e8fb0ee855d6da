#!/usr/bin/env python3
"""Time one-shot `register` processes with and without the launcher's malloc settings.

Usage: scripts/bench_tunables.py BIN SHARED [--reps N] [--args "--trust-position"]

BIN is the `horizonreg` launcher (build/horizonreg). Every real photo of
SHARED/real/*/ with a NAME.truth.json is registered at its true position, once
per repetition in each setting in turn:
  launcher  GLIBC_TUNABLES unset: the launcher sets its huge-page heap
  glibc     GLIBC_TUNABLES empty: glibc's defaults
Prints per setting the median over the photos of each photo's median
timing_ms.total, the largest, the median CPU (user + system) per process, and
the registered count; and any photo whose poses differ between the settings.
"""
import argparse
import glob
import json
import os
import statistics
import subprocess
import sys

SETTINGS = {"launcher": None, "glibc": ""}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("binary")
    ap.add_argument("shared")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--args", default="--trust-position", help="extra register arguments (default %(default)s)")
    a = ap.parse_args()
    truths = sorted(glob.glob(os.path.join(a.shared, "real", "*", "*.truth.json")))
    if not truths:
        print(f"no real photos under {a.shared}/real", file=sys.stderr)
        return 2
    runs = {k: {} for k in SETTINGS}
    for _ in range(a.reps):
        for tf in truths:
            t = json.load(open(tf))
            name = os.path.basename(tf)[: -len(".truth.json")]
            image = os.path.join(os.path.dirname(tf), t.get("image", name + ".jpg"))
            for key, value in SETTINGS.items():
                env = dict(os.environ)
                env.pop("GLIBC_TUNABLES", None)
                if value is not None:
                    env["GLIBC_TUNABLES"] = value
                cmd = ["/usr/bin/time", "-f", "%U %S", a.binary, "register", image,
                       "--dem", os.path.join(a.shared, "dem", t["dem"]),
                       "--lat", str(t["lat"]), "--lon", str(t["lon"]), "--alt", str(t["alt_m"])] + a.args.split()
                p = subprocess.run(cmd, env=env, capture_output=True, text=True)
                d = json.loads(p.stdout)
                user, system = map(float, p.stderr.split()[-2:])
                runs[key].setdefault(name, []).append(
                    (d["timing_ms"]["total"], user + system, d["status"], d.get("azimuth_deg"), d.get("pitch_deg")))
    for key, per in runs.items():
        totals = [statistics.median(r[0] for r in v) for v in per.values()]
        cpus = [statistics.median(r[1] for r in v) for v in per.values()]
        registered = sum(v[0][2] == "registered" for v in per.values())
        print(f"{key:9s} total median {statistics.median(totals):7.1f} ms  max {max(totals):7.1f} ms  "
              f"cpu median {statistics.median(cpus):.3f} s  registered {registered}/{len(per)}")
        print("          " + " ".join(f"{x:.0f}" for x in totals))
    differ = 0
    for name in runs["launcher"]:
        poses = {key: {r[2:] for r in runs[key][name]} for key in runs}
        if len({frozenset(p) for p in poses.values()}) > 1:
            differ += 1
            print("poses differ:", name, poses)
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
