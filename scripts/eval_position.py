#!/usr/bin/env python3
"""Position refinement (issue 15): `register --refine-position` from a position that is off.

The rendered dev scenes (SHARED/scenes/dev) and the real photos (SHARED/real/*/) are registered
from their true position moved by a known amount (30 m horizontally in a few directions, 20 m up or
down), and the refined position is compared with the truth: horizontal and vertical error before
(the offset) and after, the observable flag, the orientation error (azimuth and pitch; of the centre
ray for the real photos, whose truth is that ray) and the time of the refinement (timing_ms.position).
Mode `wrong` registers the dev scenes from 2-10 km away with --refine-position: every one must
answer no_match, or be one that plain `register` (no refinement) registers as well (the eye at the
true altitude 5 km away can be an aerial view that the matching alone takes: issue 4's limit).

Usage: eval_position.py HORIZONREG SHARED_DIR [--modes dev,real,wrong] [--directions N] [--only NAME,...]
       [--check] [--floor R] [--or-floor R2] [--baseline]
--baseline also registers every case without --refine-position (the orientation error before).
Mode dev also tells, for each height reported observable but more than 3 m off, whose miss it is:
the photo registered with --trust-position at the truth and at the estimate (rms of the skyline's
fit, inliers). Where the estimate fits better than the truth, the skyline and DEM prefer the
estimate (the model's limit: the renderer's terrain is not ours to the metre); where the truth fits
better, the prior's pull towards the given position (a posterior sigma of s against the prior's 10 m
draws the estimate (s / 10)^2 of the 20 m offset back) or the search stopped short of it.
With --check, exits 1 (printing FAIL) when, over the registered dev `match` scenes whose height is
reported observable, less than R (default 0.8, the issue's target) are within 3 m vertically, when
less than R2 (default 0.9) of the registered are within 0.3 deg in orientation, when any registration is false
(> 1 deg), or when a wrong-position probe registers that plain `register` does not. Refinements
over 1 s are reported, not failed: wall-clock time on a shared 2-core machine measures its load
(make bench measures the time).
"""
import json, math, os, statistics, subprocess, sys, tempfile

# (bearing deg, horizontal m, up m) of the given position from the truth.
OFFSETS = [(45, 30.0, 20.0), (165, 30.0, -20.0), (285, 30.0, 20.0), (0, 0.0, 0.0)]
WRONG = [(0, 2000), (120, 5000), (240, 10000)]
A, E2 = 6378137.0, 6.69437999014e-3  # WGS84


def radii(lat):
    s = math.sin(math.radians(lat))
    w = math.sqrt(1 - E2 * s * s)
    return A * (1 - E2) / w ** 3, A / w  # meridian, prime vertical


def move(lat, lon, bearing_deg, dist_m):
    m, n = radii(lat)
    b = math.radians(bearing_deg)
    return (lat + math.degrees(dist_m * math.cos(b) / m),
            lon + math.degrees(dist_m * math.sin(b) / (n * math.cos(math.radians(lat)))))


def enu_error(lat, lon, lat0, lon0):
    m, n = radii(lat0)
    return (math.radians(lon - lon0) * n * math.cos(math.radians(lat0)), math.radians(lat - lat0) * m)


def angdiff(a, b):
    return (a - b + 180.0) % 360.0 - 180.0


def register(binary, image, dem, lat, lon, alt, extra=(), refine=True):
    with tempfile.NamedTemporaryFile(suffix=".json") as tmp:
        cmd = [binary, "register", image, "--dem", dem, "--lat", repr(lat), "--lon", repr(lon), "--alt", repr(alt),
               "--json", tmp.name] + (["--refine-position"] if refine else []) + list(extra)
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            return {"status": "error", "message": p.stderr.strip()[:160]}
        return json.load(open(tmp.name))


def fmt(v, f):
    return format(v, f) if v is not None else "-"


def table(title, cases, binary, baseline=False):
    """cases: (name, expect, image, dem, truth lat, lon, eye height, yaw, pitch, centre_ray, offsets)"""
    print(f"\n== {title} ==")
    print(f"{'scene':<24}{'expect':<9}{'offset':>13}  {'status':<11}{'dh0':>6}{'dh':>7}{'dv0':>6}{'dv':>7}"
          f"{'sig_h':>7}{'sig_v':>7}{'obs':>5}{'d_az':>8}{'d_pitch':>8}{'pos_ms':>7}{'ms':>6}  note")
    rows = []
    for name, expect, image, dem, lat, lon, eye, yaw, pitch, centre, offsets in cases:
        for bearing, dist, up in offsets:
            glat, glon = move(lat, lon, bearing, dist)
            r = register(binary, image, dem, glat, glon, eye + up)
            row = {"name": name, "expect": expect, "offset": (bearing, dist, up), "status": r.get("status"),
                   "dh0": dist, "dv0": abs(up), "ms": (r.get("timing_ms") or {}).get("total")}
            pos = r.get("position")
            note = ""
            if pos:
                de, dn = enu_error(pos["lat"], pos["lon"], lat, lon)
                row["dh"] = math.hypot(de, dn)
                row["de"], row["dn"] = de, dn
                row["dv"] = pos["eye_height_m"] - eye
                row["sig_h"] = math.hypot(pos["sigma_east_m"], pos["sigma_north_m"])
                row["sig_v"] = pos["sigma_up_m"]
                row["obs"] = pos["observable"]
                row["pos_ms"] = r["timing_ms"].get("position")
                axes = pos.get("observable_axes", {})
                row["obs_str"] = "".join(k[0] for k in ("east", "north", "up") if axes.get(k)) or "-"
                row["case"] = (image, dem, lat, lon, eye)
                row["estimate"] = (pos["lat"], pos["lon"], pos["eye_height_m"])
                note = pos.get("message", "")
            if r.get("status") == "registered":
                if centre:
                    row["daz"] = angdiff(r["center_ray"]["azimuth_deg"], yaw)
                    row["dp"] = r["center_ray"]["elevation_deg"] - pitch
                else:
                    row["daz"] = angdiff(r["azimuth_deg"], yaw)
                    row["dp"] = r["pitch_deg"] - pitch
                row["false"] = max(abs(row["daz"]), abs(row["dp"])) > 1.0
                if row["false"]:
                    note = "FALSE REGISTRATION " + note
            else:
                row["false"] = False
                note = (r.get("message") or "")[:50] + "; " + note
            if baseline:  # the same without --refine-position
                b = register(binary, image, dem, glat, glon, eye + up, refine=False)
                row["base"] = b.get("status")
                if b.get("status") == "registered":
                    cr = b["center_ray"]
                    row["base_daz"] = angdiff(cr["azimuth_deg"] if centre else b["azimuth_deg"], yaw)
                    row["base_dp"] = (cr["elevation_deg"] if centre else b["pitch_deg"]) - pitch
                    note = f"[plain {row['base_daz']:+.3f}/{row['base_dp']:+.3f}] " + note
                else:
                    note = "[plain no_match] " + note
            rows.append(row)
            print(f"{name:<24}{expect:<9}{bearing:>4}/{dist:>3.0f}/{up:>+4.0f}  {row['status']:<11}"
                  f"{dist:>6.0f}{fmt(row.get('dh'), '7.2f')}{abs(up):>6.0f}{fmt(row.get('dv'), '+7.2f')}"
                  f"{fmt(row.get('sig_h'), '7.2f')}{fmt(row.get('sig_v'), '7.2f')}{row.get('obs_str', '-'):>5}"
                  f"{fmt(row.get('daz'), '8.3f')}{fmt(row.get('dp'), '8.3f')}{fmt(row.get('pos_ms'), '7.0f')}"
                  f"{fmt(row['ms'], '6.0f')}  {note[:90]}")
    return rows


def height_misses(rows, binary):
    """For each registered row whose height is reported observable and more
    than 3 m off: the photo registered (--trust-position, no refinement) at
    the truth and at the estimate."""
    misses = [x for x in rows if x["status"] == "registered" and "u" in x.get("obs_str", "") and abs(x["dv"]) > 3.0]
    if not misses:
        return
    print("heights observable and more than 3 m off: the fit at the truth and at the estimate (--trust-position)")
    print(f"{'scene':<24}{'offset':>13}{'dv':>7}{'sig_v':>7}{'rms@truth':>10}{'inl':>6}{'rms@est':>9}{'inl':>6}  whose")
    model = search = 0
    for x in misses:
        image, dem, lat, lon, eye = x["case"]
        fits = []
        for at in ((lat, lon, eye), x["estimate"]):
            r = register(binary, image, dem, *at, extra=["--trust-position"], refine=False)
            fits.append((r.get("rms_px"), r.get("inlier_fraction")) if r.get("status") == "registered" else (None, None))
        (rt, it), (re_, ie) = fits
        whose = "model" if rt is not None and re_ is not None and re_ < rt else "prior/search"
        model, search = model + (whose == "model"), search + (whose != "model")
        b, d, u = x["offset"]
        print(f"{x['name']:<24}{b:>4}/{d:>3.0f}/{u:>+4.0f}{x['dv']:>+7.2f}{x['sig_v']:>7.2f}{fmt(rt, '10.3f')}"
              f"{fmt(it, '6.2f')}{fmt(re_, '9.3f')}{fmt(ie, '6.2f')}  {whose}")
    print(f"height misses: {len(misses)}; the estimate fits better than the truth (the model's): {model}; "
          f"the truth fits better (the prior's pull or the search's): {search}")


def summary(rows, label):
    reg = [x for x in rows if x["status"] == "registered"]
    obs = [x for x in reg if x.get("obs")]
    up = [x for x in reg if "u" in x.get("obs_str", "")]
    hor = [x for x in reg if "e" in x.get("obs_str", "") and "n" in x.get("obs_str", "")]
    up_ok = [x for x in up if abs(x["dv"]) <= 3.0]
    hor_ok = [x for x in hor if x["dh"] <= 5.0]
    good_pos = [x for x in obs if x["dh"] <= 5.0 and abs(x["dv"]) <= 3.0]
    good_or = [x for x in reg if abs(x["daz"]) <= 0.3 and abs(x["dp"]) <= 0.3]
    false = [f"{x['name']}@{x['offset'][0]}" for x in rows if x["false"]]
    times = [x["pos_ms"] for x in rows if x.get("pos_ms") is not None]
    med = lambda k, xs: statistics.median(abs(x[k]) for x in xs) if xs else float("nan")
    print(f"{label}: registered {len(reg)}/{len(rows)}; orientation within 0.3 deg: {len(good_or)}/{len(reg)}; "
          f"false (> 1 deg): {len(false)} {false}")
    print(f"{label}: all three axes observable: {len(obs)} (within 5 m / 3 m: {len(good_pos)}); height observable: "
          f"{len(up)}, of those within 3 m: {len(up_ok)} (median |dv| {med('dv', up):.2f} m, was 20); east and north "
          f"observable: {len(hor)}, of those within 5 m: {len(hor_ok)}")
    # Each horizontal axis alone where it is reported observable (near
    # terrain ahead tells the distance to it, not the sideways position).
    axis = []
    for k, name in (("e", "east"), ("n", "north")):
        xs = [x for x in reg if k in x.get("obs_str", "")]
        ok = [x for x in xs if abs(x["d" + k]) <= 5.0]
        axis.append(f"{name} {len(xs)}, within 5 m {len(ok)} (median |d{k}| {med('d' + k, xs):.2f} m)")
    print(f"{label}: one horizontal axis observable: " + "; ".join(axis))
    print(f"{label}: median error over the registered: horizontal {med('dh', reg):.2f} m, vertical {med('dv', reg):.2f} m; "
          f"refinement time (timing_ms.position) median {statistics.median(times) if times else float('nan'):.0f} ms, "
          f"max {max(times) if times else float('nan'):.0f} ms")
    if any("base" in x for x in rows):
        breg = [x for x in rows if x.get("base") == "registered"]
        bgood = [x for x in breg if abs(x["base_daz"]) <= 0.3 and abs(x["base_dp"]) <= 0.3]
        bfalse = [x for x in breg if max(abs(x["base_daz"]), abs(x["base_dp"])) > 1.0]
        print(f"{label}: without --refine-position: registered {len(breg)}/{len(rows)}; orientation within 0.3 deg: "
              f"{len(bgood)}/{len(breg)}; false (> 1 deg): {len(bfalse)}")
    return reg, up, up_ok, good_or, false, times


def main():
    argv = sys.argv[1:]
    opt = lambda k, d=None: argv[argv.index(k) + 1] if k in argv else d
    check = "--check" in argv
    modes = opt("--modes", "dev,real,wrong").split(",")
    only = set(opt("--only").split(",")) if opt("--only") else None
    ndir = int(opt("--directions", "3"))
    floor = float(opt("--floor", "0.8"))
    or_floor = float(opt("--or-floor", "0.9"))
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and
            (i == 0 or argv[i - 1] not in ("--modes", "--only", "--directions", "--floor", "--or-floor"))]
    if len(args) != 2 or "--help" in sys.argv or "-h" in sys.argv:
        print(__doc__)
        return 0 if ("--help" in sys.argv or "-h" in sys.argv) else 2
    binary, shared = args[0], args[1]
    scenes = os.path.join(shared, "scenes", "dev")
    if not os.path.isdir(scenes):
        print("SKIPPED: ../shared/scenes/dev is absent")
        return 77  # CTest: SKIP_RETURN_CODE
    failed = False
    offsets = OFFSETS[:ndir]
    if "dev" in modes or "wrong" in modes:
        dev = []
        for f in sorted(os.listdir(scenes)):
            if not f.endswith(".truth.json") or (only and f[:-11] not in only):
                continue
            t = json.load(open(os.path.join(scenes, f)))
            dev.append((f[:-11], t["expect"], os.path.join(scenes, t["image"]), os.path.join(shared, "dem", t["dem"]),
                        t["lat"], t["lon"], t["eye_height_m"], t["yaw_deg"], t["pitch_deg"], False, offsets))
    if "dev" in modes:
        rows = table("dev scenes, given position 30 m off horizontally and 20 m vertically", dev, binary,
                     "--baseline" in argv)
        reg, up, up_ok, good_or, false, times = summary([x for x in rows if x["expect"] == "match"], "match scenes")
        height_misses([x for x in rows if x["expect"] == "match"], binary)
        summary([x for x in rows if x["expect"] != "match"], "hard and fog scenes")
        if check:
            rate = len(up_ok) / len(up) if up else 0.0
            or_rate = len(good_or) / len(reg) if reg else 0.0
            # Times are reported, not checked: with other work on this 2-core
            # machine a refinement took 1.0-1.5 s that takes 0.26-0.31 s idle
            # (make bench, BM_RefinePosition, measures it).
            slow = [t for t in times if t > 1000.0]
            if rate < floor or or_rate < or_floor or false:
                print(f"FAIL: dev: {100 * rate:.0f}% of the height-observable within 3 m (floor {100 * floor:.0f}%), "
                      f"{100 * or_rate:.0f}% within 0.3 deg (floor {100 * or_floor:.0f}%), {len(false)} false")
                failed = True
            elif slow:
                print(f"note: {len(slow)} refinements over 1 s (wall clock, this machine's load included)")
    if "real" in modes:
        real = os.path.join(shared, "real")
        cases = []
        for sub in sorted(os.listdir(real)) if os.path.isdir(real) else []:
            d = os.path.join(real, sub)
            if not os.path.isdir(d):
                continue
            for f in sorted(os.listdir(d)):
                if f.endswith(".truth.json") and (not only or f[:-11] in only):
                    t = json.load(open(os.path.join(d, f)))
                    cases.append((f[:-11], t.get("expect", "match"), os.path.join(d, t["image"]),
                                  os.path.join(shared, "dem", t["dem"]), t["lat"], t["lon"], t["alt_m"],
                                  t["yaw_deg"], t["pitch_deg"], True, offsets[:1]))
        if cases:
            rows = table("real photos, given position 30 m off horizontally and 20 m vertically", cases, binary,
                         "--baseline" in argv)
            reg, up, up_ok, good_or, false, times = summary(rows, "real photos")
            if check and false:
                print("FAIL: real: a false registration")
                failed = True
    if "wrong" in modes:
        probes = [c[:10] + ([(b, d, 0.0) for b, d in WRONG],) for c in dev if c[1] == "match"]
        probes = probes[::3]  # every third scene: the probes are many and alike
        rows = table("dev scenes from 2-10 km away (must be no_match)", probes, binary)
        bad = [x for x in rows if x["status"] == "registered"]
        # The same probe without --refine-position: a registration there is
        # the matching's own (issue 4's), not the refinement's.
        also_plain = []
        for x in bad:
            c = next(c for c in probes if c[0] == x["name"])
            b, d, _ = x["offset"]
            lat, lon = move(c[4], c[5], b, d)
            if register(binary, c[2], c[3], lat, lon, c[6], refine=False).get("status") == "registered":
                also_plain.append(x)
        names = lambda xs: [f"{x['name']}@{x['offset'][1]:.0f}m" for x in xs]
        new = [x for x in bad if x not in also_plain]
        print(f"wrong positions: {len(rows)} probes, registered: {len(bad)} {names(bad)}; of those also without "
              f"--refine-position: {names(also_plain)}; by the refinement alone: {len(new)} {names(new)}")
        if check and new:
            print("FAIL: wrong: the refinement registered from 2-10 km away")
            failed = True
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
