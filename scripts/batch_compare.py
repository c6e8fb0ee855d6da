#!/usr/bin/env python3
"""`horizonreg batch` against `horizonreg register`, photo by photo.

Usage: batch_compare.py HORIZONREG SHARED_DIR [--threads N] [--sets dev,real]

Writes one manifest per DEM (the rendered dev scenes: lat, lon, agl_m; the
real photos of real/columbia: lat, lon, alt_m), runs `batch` on each and
`register` on every photo with the same position, and compares the JSON
rows field by field (timing_ms, image and station aside), the batch run with
--check-every-photo. Then again without it: a station's photos after two
have passed the position check skip its wide look, and their rows must be
register's but for the "position_check" block (which says who vouched), or
where register answers no_match, registered within the station camera's
opening angle ("hfov_search_deg" says "station").
Prints a table and the batch throughput both ways; exits 1 when a row
differs or is missing, 77 when the shared data is absent (CTest: skipped).
"""
import collections
import json
import os
import subprocess
import sys
import tempfile
import time


def strip(row):
    return {k: v for k, v in row.items() if k not in ("timing_ms", "image", "station")}


def diff(a, b, path=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            d = diff(a.get(k), b.get(k), path + "." + k)
            if d:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            d = diff(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{path}: batch {a!r} register {b!r}"


def photos(shared, sets):
    out = []  # (set, dem, image, lat, lon, height option, value)
    for name, folder, key in (("dev", ("scenes", "dev"), "agl_m"), ("real", ("real", "columbia"), "alt_m")):
        if name not in sets:
            continue
        d = os.path.join(shared, *folder)
        for f in sorted(os.listdir(d)):
            if f.endswith(".truth.json"):
                t = json.load(open(os.path.join(d, f)))
                out.append((name, t["dem"], os.path.join(d, t["image"]), t["lat"], t["lon"], key, t[key]))
    return out


def main(argv):
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and (i == 0 or argv[i - 1] not in ("--threads", "--sets"))]
    if len(args) != 2:
        print(__doc__)
        return 2
    binary, shared = args[0], os.path.abspath(args[1])
    threads = argv[argv.index("--threads") + 1] if "--threads" in argv else "2"
    sets = (argv[argv.index("--sets") + 1] if "--sets" in argv else "dev,real").split(",")
    if not os.path.isdir(os.path.join(shared, "scenes", "dev")):
        print(f"SKIP: {shared} has no scenes/dev (shared data absent)")
        return 77
    by_dem = collections.defaultdict(list)
    for p in photos(shared, sets):
        by_dem[p[1]].append(p)
    bad = 0
    total = 0
    batch_s = vouched_s = 0.0
    vouched_rows = 0
    print(f"{'photo':34s} {'set':5s} {'status':11s} same")
    with tempfile.TemporaryDirectory() as tmp:
        for dem, group in sorted(by_dem.items()):
            manifest = os.path.join(tmp, dem + ".csv")
            with open(manifest, "w") as f:
                f.write("image,lat,lon,alt_m,agl_m\n")
                for _, _, image, lat, lon, key, value in group:
                    f.write(f"{image},{lat!r},{lon!r},{value if key == 'alt_m' else ''},{value if key == 'agl_m' else ''}\n")
            runs = {}
            for how, extra in (("every", ["--check-every-photo"]), ("vouched", [])):
                out = os.path.join(tmp, f"{dem}.{how}.jsonl")
                t0 = time.time()
                subprocess.run([binary, "batch", manifest, "--dem", os.path.join(shared, "dem", dem), "-o", out,
                                "--threads", threads, "--no-progress"] + extra, check=True)
                if how == "every":
                    batch_s += time.time() - t0
                else:
                    vouched_s += time.time() - t0
                runs[how] = {}
                for line in open(out):
                    r = json.loads(line)
                    runs[how][r["image"]] = r
            rows = runs["every"]
            for s, _, image, lat, lon, key, value in group:
                total += 1
                p = subprocess.run([binary, "register", image, "--dem", os.path.join(shared, "dem", dem),
                                    "--lat", repr(lat), "--lon", repr(lon),
                                    "--alt" if key == "alt_m" else "--agl", repr(value)],
                                   capture_output=True, text=True)
                name = os.path.basename(image)
                if p.returncode != 0:
                    print(f"{name:34s} {s:5s} register failed: {p.stderr.strip()}")
                    bad += 1
                    continue
                ref = json.loads(p.stdout)
                row = rows.get(image)
                d = "missing from the batch output" if row is None else diff(strip(row), strip(ref))
                if row is not None and row["status"] == "error":
                    d = "batch error: " + row["message"]
                v = runs["vouched"].get(image)
                light = v is not None and "station_vouched_by" in (v.get("position_check") or {})
                by_station = v is not None and (v.get("hfov_search_deg") or [None] * 3)[2] == "station"
                if v is None:
                    dv = "missing from the vouched batch output"
                elif by_station:  # registered again within the station camera's opening angle: register's no_match
                    dv = None if ref["status"] == "no_match" else f"station angle row, register says {ref['status']}"
                elif light:
                    dv = diff({k: x for k, x in strip(v).items() if k != "position_check"},
                              {k: x for k, x in strip(ref).items() if k != "position_check"})
                else:
                    dv = diff(strip(v), strip(ref))
                vouched_rows += light
                print(f"{name:34s} {s:5s} {ref['status']:11s} {'yes' if d is None else 'NO: ' + d}"
                      f"{'; vouched: ' + ('same' if dv is None else 'NO: ' + dv) if light else ''}"
                      f"{'' if light or dv is None else '; vouched run: NO: ' + dv}")
                bad += d is not None or dv is not None
    print(f"batch == register on {total - bad}/{total} photos; batch wall time {batch_s:.1f} s "
          f"for {total} photos in {len(by_dem)} batches (DEM load and horizon included); "
          f"with the stations' vouch (no --check-every-photo) {vouched_s:.1f} s, {vouched_rows} rows vouched")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
