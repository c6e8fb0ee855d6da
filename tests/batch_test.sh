#!/bin/bash
# End-to-end tests of `horizonreg batch` and --dem-dir (issue 8), on the
# rendered dev scenes of ../shared: a corrupt and a missing photo become error
# rows and the batch goes on; kill -9 in the middle and a restart give every
# photo exactly once; the CSV table holds every row; a folder of DEM tiles
# gives the same horizon as the tiles given one by one. Exit 77 (CTest:
# skipped) without ../shared.
set -u
BIN=$1
SHARED=$(cd "$2" 2>/dev/null && pwd)
if [ -z "$SHARED" ] || [ ! -d "$SHARED/scenes/dev" ]; then echo "SKIPPED: ../shared is absent"; exit 77; fi
PY=python3
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
DEV=$SHARED/scenes/dev

# Manifest of the Alps scenes (one DEM), positions from the truth files.
$PY - "$DEV" "$TMP/alps.csv" <<'PYEOF'
import json, os, sys
dev, out = sys.argv[1], sys.argv[2]
rows = ["image,lat,lon,agl_m,station"]
for n in sorted(os.listdir(dev)):
    if n.startswith("alps") and n.endswith(".truth.json"):
        t = json.load(open(os.path.join(dev, n)))
        rows.append(f"{os.path.join(dev, t['image'])},{t['lat']!r},{t['lon']!r},{t['agl_m']},{n.split('_')[0]}")
open(out, "w").write("\n".join(rows) + "\n")
PYEOF
N=$(($(wc -l < "$TMP/alps.csv") - 1))
[ "$N" -ge 6 ] || fail "expected at least 6 alps scenes, found $N"

# 1. A corrupt photo (truncated JPEG) and a missing one in the middle.
head -c 20000 "$DEV/alps_01.jpg" > "$TMP/corrupt.jpg"
{ head -n 3 "$TMP/alps.csv"; echo "corrupt.jpg,47.3,9.4,2,"; echo "missing.jpg,47.3,9.4,2,"; tail -n +4 "$TMP/alps.csv"; } > "$TMP/mixed.csv"
"$BIN" batch "$TMP/mixed.csv" --dem "$SHARED/dem/N47E009.hgt" -o "$TMP/mixed.jsonl" --csv "$TMP/mixed.csv.out" \
  --no-progress 2> "$TMP/err" || fail "batch with a corrupt photo exited $?: $(cat "$TMP/err")"
$PY - "$TMP/mixed.jsonl" "$((N + 2))" <<'PYEOF' || fail "corrupt-photo batch rows"
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
assert len(rows) == int(sys.argv[2]), f"{len(rows)} rows, expected {sys.argv[2]}"
errors = [r for r in rows if r["status"] == "error"]
assert sorted(r["image"] for r in errors) == ["corrupt.jpg", "missing.jpg"], errors
assert all("'" in r["message"] for r in errors), [r["message"] for r in errors]
ok = [r for r in rows if r["status"] == "registered"]
assert len(ok) >= len(rows) - 4, f"only {len(ok)} registered"
print(f"corrupt/missing photos: {len(errors)} error rows, {len(ok)} registered of {len(rows)}")
PYEOF
[ "$(wc -l < "$TMP/mixed.csv.out")" -eq "$((N + 3))" ] || fail "CSV has $(wc -l < "$TMP/mixed.csv.out") lines, expected $((N + 3))"
head -n 1 "$TMP/mixed.csv.out" | grep -q '^image,station,status,azimuth_deg' || fail "CSV header"

# 2. kill -9 in the middle, a half-written last line, then a restart.
"$BIN" batch "$TMP/alps.csv" --dem "$SHARED/dem/N47E009.hgt" -o "$TMP/killed.jsonl" --threads 1 --no-progress 2>/dev/null &
PID=$!
for _ in $(seq 1 300); do
  [ -s "$TMP/killed.jsonl" ] && [ "$(wc -l < "$TMP/killed.jsonl")" -ge 2 ] && break
  sleep 0.05
done
kill -9 $PID 2>/dev/null
wait $PID 2>/dev/null
BEFORE=$(wc -l < "$TMP/killed.jsonl")
[ "$BEFORE" -lt "$N" ] || fail "the batch finished before it could be killed ($BEFORE rows)"
printf '{"image": "half-writ' >> "$TMP/killed.jsonl"   # what a kill inside a write() would leave
"$BIN" batch "$TMP/alps.csv" --dem "$SHARED/dem/N47E009.hgt" -o "$TMP/killed.jsonl" --no-progress 2> "$TMP/err" \
  || fail "resume exited $?: $(cat "$TMP/err")"
grep -q "($BEFORE already done)" "$TMP/err" || fail "resume did not skip the $BEFORE finished rows: $(cat "$TMP/err")"
"$BIN" batch "$TMP/alps.csv" --dem "$SHARED/dem/N47E009.hgt" -o "$TMP/whole.jsonl" --no-progress 2>/dev/null || fail "uninterrupted batch"
$PY - "$TMP/killed.jsonl" "$TMP/whole.jsonl" "$N" <<'PYEOF' || fail "kill -9 and resume"
import json, sys
killed = [json.loads(l) for l in open(sys.argv[1])]  # every line parses: no half-written line left
whole = {r["image"]: r for r in map(json.loads, open(sys.argv[2]))}
images = [r["image"] for r in killed]
assert len(images) == int(sys.argv[3]) and len(set(images)) == len(images), f"{len(images)} rows, {len(set(images))} distinct"
for r in killed:
    a = {k: v for k, v in r.items() if k != "timing_ms"}
    b = {k: v for k, v in whole[r["image"]].items() if k != "timing_ms"}
    assert a == b, f"{r['image']}: the resumed row differs from the uninterrupted one"
print(f"kill -9: {len(images)} photos, each exactly once, rows equal to an uninterrupted run")
PYEOF
echo "resume: $BEFORE rows kept after kill -9, the rest added"

# 3. A folder of tiles: the Pyrenees two-tile mosaic found by extent equals --dem --dem.
"$BIN" horizon --dem-dir "$SHARED/dem" --lat 42.02 --lon 1.8 -o "$TMP/dir.json" || fail "horizon --dem-dir"
"$BIN" horizon --dem "$SHARED/dem/N41E001.hgt" --dem "$SHARED/dem/N42E001.hgt" --lat 42.02 --lon 1.8 -o "$TMP/two.json"
"$BIN" horizon --dem "$SHARED/dem/N42E001.hgt" --lat 42.02 --lon 1.8 -o "$TMP/one.json"
cmp -s "$TMP/dir.json" "$TMP/two.json" || fail "--dem-dir differs from --dem N41E001.hgt --dem N42E001.hgt"
cmp -s "$TMP/dir.json" "$TMP/one.json" && fail "the southern tile makes no difference at 42.02 N (bad test point)"
echo "--dem-dir: Pyrenees mosaic identical to the explicit two tiles"

# 4. Sea-level fill on the half-sea tile N48W125: the sea horizon appears where
# the tile has no data, and nothing changes over land.
"$BIN" horizon --dem-dir "$SHARED/dem" --lat 48.155 --lon -124.59 --agl 50 -o "$TMP/nofill.json" || fail "coastal horizon"
"$BIN" horizon --dem-dir "$SHARED/dem" --lat 48.155 --lon -124.59 --agl 50 --sea-level-fill -o "$TMP/fill.json" || fail "--sea-level-fill"
$PY - "$TMP/nofill.json" "$TMP/fill.json" <<'PYEOF' || fail "sea-level fill"
import json, math, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
changed = [i for i, (x, y) in enumerate(zip(a["elevation_deg"], b["elevation_deg"])) if x != y]
assert changed, "the fill changed nothing"
land = [i for i, x in enumerate(a["elevation_deg"]) if x is not None and x > 0.0]
assert all(a["elevation_deg"][i] == b["elevation_deg"][i] for i in land), "the fill moved a land horizon"
print(f"sea-level fill: {len(changed)} of {len(a['elevation_deg'])} bins now see the sea; land bins unchanged")
PYEOF
# 5. Horizons at many points: each profile of --points equals the single-point one.
printf 'id,lat,lon,agl_m\nsaentis,47.25,9.35,2\nvalley,47.3,9.5,\n"a, b",47.4,9.2,10\n' > "$TMP/points.csv"
"$BIN" horizon --dem "$SHARED/dem/N47E009.hgt" --points "$TMP/points.csv" -o "$TMP/points.json" || fail "--points"
"$BIN" horizon --dem "$SHARED/dem/N47E009.hgt" --points "$TMP/points.csv" --format csv -o "$TMP/points.csv.out" || fail "--points csv"
"$BIN" horizon --dem "$SHARED/dem/N47E009.hgt" --lat 47.25 --lon 9.35 --agl 2 -o "$TMP/p1.json"
"$BIN" horizon --dem "$SHARED/dem/N47E009.hgt" --lat 47.3 --lon 9.5 -o "$TMP/p2.json"
"$BIN" horizon --dem "$SHARED/dem/N47E009.hgt" --lat 47.4 --lon 9.2 --agl 10 -o "$TMP/p3.json"
$PY - "$TMP" <<'PYEOF' || fail "--points differs from single points"
import csv, json, sys
t = sys.argv[1]
many = json.load(open(f"{t}/points.json"))
assert [p["id"] for p in many] == ["saentis", "valley", "a, b"], [p["id"] for p in many]
rows = list(csv.DictReader(open(f"{t}/points.csv.out")))
assert len(rows) == 3 * 1440, len(rows)
for i, p in enumerate(many):
    one = json.load(open(f"{t}/p{i + 1}.json"))
    assert p["elevation_deg"] == one["elevation_deg"] and p["distance_m"] == one["distance_m"], p["id"]
    assert [float(r["elevation_deg"]) for r in rows if r["id"] == p["id"]] == one["elevation_deg"], p["id"]
print("horizon --points: 3 profiles equal to the single-point runs (JSON and CSV)")
PYEOF
# 6. --skylines: each row carries the photo's skyline, equal to register
# --skyline-out's (read again near the DEM horizon where registered, as
# extracted where not); rows without the flag carry none. Real photos.
REAL=$SHARED/real/columbia
if [ -d "$REAL" ]; then
  $PY - "$REAL" "$TMP/real.csv" "$TMP/real.expected.json" <<'PYEOF'
import json, math, sys
real, out, expected_out = sys.argv[1:4]
rows = ["image,lat,lon,alt_m"]
# Registers; registers through the faint second look (a hazy far range the
# extraction nulled); given a position 3 km away (bearing 120), must not.
expected = {"AK01b_20090827_202939": (0, "registered"), "CG05_20050811_190000": (0, "registered"),
            "AK10_20090803_195410": (3, "no_match")}
json.dump({n: status for n, (_, status) in expected.items()}, open(expected_out, "w"))
for n, (km, _) in expected.items():
    t = json.load(open(f"{real}/{n}.truth.json"))
    lat = t["lat"] + km * 1000 * math.cos(math.radians(120)) / 111320
    lon = t["lon"] + km * 1000 * math.sin(math.radians(120)) / (111320 * math.cos(math.radians(t["lat"])))
    rows.append(f"{real}/{t['image']},{lat!r},{lon!r},{t['alt_m']!r}")
open(out, "w").write("\n".join(rows) + "\n")
PYEOF
  "$BIN" batch "$TMP/real.csv" --dem "$SHARED/dem/dem_Columbia.tif" --skylines -o "$TMP/real.jsonl" --no-progress \
    2> "$TMP/err" || fail "batch --skylines exited $?: $(cat "$TMP/err")"
  while IFS=, read -r IMG LAT LON ALT; do
    n=$(basename "$IMG" .jpg)
    "$BIN" register "$IMG" --dem "$SHARED/dem/dem_Columbia.tif" --lat "$LAT" --lon "$LON" --alt "$ALT" \
      --skyline-out "$TMP/$n.skyline.json" > "$TMP/$n.reg.json" || fail "register --skyline-out $n"
    "$BIN" skyline "$IMG" --json "$TMP/$n.extracted.json" || fail "skyline $n"
  done < <(tail -n +2 "$TMP/real.csv")
  $PY - "$TMP" "$REAL" <<'PYEOF' || fail "batch --skylines"
import json, os, sys
t, real = sys.argv[1], sys.argv[2]
rows = {os.path.basename(r["image"])[:-4]: r for r in map(json.loads, open(f"{t}/real.jsonl"))}
for n, status in json.load(open(f"{t}/real.expected.json")).items():
    r = rows[n]
    assert r["status"] == status, (n, r["status"], r["message"])
    ref = json.load(open(f"{t}/{n}.skyline.json"))
    extracted = json.load(open(f"{t}/{n}.extracted.json"))
    assert r["skyline"] == ref, f"{n}: the row's skyline differs from register --skyline-out's"
    moved = sum(a != b for a, b in zip(r["skyline"]["y"], extracted["y"]))
    # Registered: columns read again near the DEM horizon; not registered: the extracted skyline.
    assert (moved > 0) == (status == "registered"), (n, moved)
    print(f"batch --skylines {n}: {status}, equal to register --skyline-out, {moved} columns read again")
assert not any("skyline" in json.loads(l) for l in open(f"{t}/whole.jsonl")), "a row without --skylines has one"
PYEOF
else
  echo "no real photos: --skylines not tested"
fi
echo "PASS"
