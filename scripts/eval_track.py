#!/usr/bin/env python3
"""Tracking accuracy on ../shared/scenes/seq/rainier_pan (issue 6's figures).

Runs `horizonreg track` on the 60-frame pan with its drifting sensor log and
compares the poses CSV with rainier_pan.truth.csv. Error of a frame = max of
|azimuth error| and |pitch error|. Prints per frame and the summary: clear
frames median and 95th percentile, fog frames 95th percentile, frames without
a pose, sources, time.
Usage: eval_track.py HORIZONREG SHARED_DIR [--check] [--video OUT.mp4]
With --check, exits 1 when: clear median > 0.1 deg, clear p95 > 0.3 deg, fog
p95 > 1.5 deg, or any frame without a pose.
"""
import csv, json, os, subprocess, sys, tempfile, time


def pct(values, q):
    v = sorted(values)
    if not v:
        return float("nan")
    k = (len(v) - 1) * q
    lo = int(k)
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (k - lo)


def main():
    argv = sys.argv[1:]
    check = "--check" in argv
    video = argv[argv.index("--video") + 1] if "--video" in argv else None
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and (i == 0 or argv[i - 1] != "--video")]
    if len(args) != 2 or "--help" in sys.argv or "-h" in sys.argv:
        print(__doc__)
        return 0 if ("--help" in sys.argv or "-h" in sys.argv) else 2
    binary, shared = args[0], args[1]
    seq = os.path.join(shared, "scenes", "seq")
    if not os.path.isdir(seq):
        print("SKIPPED: ../shared/scenes/seq is absent")
        return 77  # CTest: SKIP_RETURN_CODE
    meta = json.load(open(os.path.join(seq, "rainier_pan.json")))
    truth = {int(r["frame"]): r for r in csv.DictReader(open(os.path.join(seq, "rainier_pan.truth.csv")))}
    with tempfile.TemporaryDirectory() as tmp:
        poses_path = os.path.join(tmp, "poses.csv")
        cmd = [binary, "track", os.path.join(seq, "rainier_pan_%04d.jpg"),
               "--dem", os.path.join(shared, "dem", meta["dem"]), "--lat", str(meta["lat"]), "--lon", str(meta["lon"]),
               "--agl", str(meta["agl_m"]), "--sensors", os.path.join(seq, "rainier_pan.sensors.csv"),
               "--fps", str(meta["fps"]), "--poses", poses_path]
        if video:
            cmd += ["-o", video]
        start = time.time()
        subprocess.run(cmd, check=True)
        wall = time.time() - start
        poses = {int(r["frame"]): r for r in csv.DictReader(open(poses_path))}
    clear, fog, missing, sources = [], [], [], {}
    print(f"{'frame':>5} {'weather':<7} {'source':<8} {'d_az':>8} {'d_pitch':>8}")
    for f in sorted(truth):
        t = truth[f]
        p = poses.get(f)
        if p is None or p["azimuth_deg"] == "":
            missing.append(f)
            print(f"{f:>5} {t['weather']:<7} {'-':<8}")
            continue
        daz = (float(p["azimuth_deg"]) - float(t["yaw_deg"]) + 180.0) % 360.0 - 180.0
        dp = float(p["pitch_deg"]) - float(t["pitch_deg"])
        err = max(abs(daz), abs(dp))
        (fog if t["weather"] == "fog" else clear).append(err)
        sources[p["source"]] = sources.get(p["source"], 0) + 1
        print(f"{f:>5} {t['weather']:<7} {p['source']:<8} {daz:8.3f} {dp:8.3f}")
    summary = (f"clear frames: {len(clear)}, median {pct(clear, 0.5):.3f} deg, p95 {pct(clear, 0.95):.3f} deg; "
               f"fog frames: {len(fog)}, p95 {pct(fog, 0.95):.3f} deg; without a pose: {len(missing)}; "
               f"sources {sources}; whole run {wall:.2f} s for {len(truth)} frames "
               f"({len(truth) / wall:.0f} fps, real time at 30 fps needs {len(truth) / 30:.1f} s)")
    print(summary)
    if check and (pct(clear, 0.5) > 0.1 or pct(clear, 0.95) > 0.3 or pct(fog, 0.95) > 1.5 or missing):
        print("FAIL: tracking misses the targets")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
