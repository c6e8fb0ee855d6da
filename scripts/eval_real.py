#!/usr/bin/env python3
"""Registration and skyline accuracy on real photographs (issue 7's figures).

Every photo of SHARED/real/*/ with a NAME.truth.json (../shared/real/README.md):
the truth is the author's camera fitted to ground control points; its
yaw_deg / pitch_deg are those of the ray through the image centre, which
`register` reports as "center_ray".

Modes (each a per-photo table and a summary):
  plain     register with no prior (position and altitude from the truth)
  camera    register --camera built from the truth's camera block
  initial   register --initial 2 deg off the truth in azimuth, then pitch (+-)
  traced    register --skyline with the hand-traced horizon (the matching alone)
  skyline   skyline accuracy against the hand-traced horizon (traced columns)
  registered-skyline  the same for `register --skyline-out` (registered with
            no prior; where registered, the skyline read again near the DEM
            horizon at the pose; --floors registered-skyline=W,
            registered-skyline-given=G)
  thin      the same on each photo cropped from the top to leave only 10 px of
            sky above the traced horizon's highest point (a camera pitched
            down, a thin strip of sky: common at time-lapse stations)
  thin-framed  (not in the default set; seconds) the same with as many rows
            cut from the bottom as from the top (the frame's foreground of
            rock gone: snow and ice to the bottom edge, as from a station on
            a glacier or a summit; --floors thin-framed=W,thin-framed-given=G,
            default 0)
  wrong     register from positions 2-10 km away and against another region's
            DEM: every one must answer no_match (a registration there is false)
  wrong-camera  the same probes with --camera from the truth (a known lens
            narrows the search to other pairs of peaks)
  wrong-initial  the same probes with --initial 2 deg off the truth (mode
            initial's four offsets in turn): a fixed camera whose approximate
            pose is known, given the wrong position or DEM. The prior keeps
            the search near the pose given, where a wrong horizon's pose can
            fit with no rival (before the fix: 2 false of 91)
  hfov      (not in the default set) plain with --hfov from the truth: a
            known opening angle (a webcam's, a manifest's hfov_deg), searched
            within +-3% (--floors hfov=N, default 12)
  wrong-hfov, ring-hfov  (not in the default set) the wrong and ring probes
            with --hfov from the truth (--floors ring-hfov=N)
  wrong-range, ring-range  (not in the default set) the same with
            --hfov-range 0.8-1.2 times the truth's: a window narrow enough to
            drop the rivals at other opening angles, wide enough for the focal
            length to absorb a wrong position's parallax (--floors ring-range=N)
  ring-noalt  (not in the default set) the ring without the altitude
            (--agl 2 instead of --alt): a wrong position given without a
            height puts the eye on the DEM's ground there, hundreds of metres
            from the true eye (--floors ring-noalt=N)
  ring-noalt-hfov  (not in the default set) the ring without the altitude
            and with --hfov from the truth: a webcam listed with its
            coordinates and opening angle, no height (--floors
            ring-noalt-hfov=N; 0 false since 2026-12-02, see the README)
  wrong-noexif  (not in the default set) the same probes with --no-exif
            (the opening angle unknown, 10-120 deg searched)
  noexif    (not in the default set) plain on the pixels alone: each photo
            decoded and saved as PNG without its EXIF, so no focal length or
            camera model narrows the opening angles searched (10-120 deg): a
            webcam frame, a scan or a stripped upload. Counts the photos within
            0.5 deg (--floors noexif=N, default 0) and the false registrations
            (must be 0)
  banner    (not in the default set; seconds) plain on each photo under a
            webcam's timestamp strip (black, 28 rows per 1000 columns, white
            text) across its top: the strip is no scene (--floors banner=N);
            wrong-banner: the wrong probes on those copies
  cloud     (not in the default set; seconds) plain on each photo under a
            cap cloud: soft white ellipses over the highest fifth of the
            skyline (the hand trace's, else the extracted one), hiding the
            summit; ring-cloud: the ring on those copies (--floors cloud=N);
            cloud-small, ring-cloud-small: a cloud over the highest tenth
  sky-cloud (not in the default set; seconds) plain on each photo with a
            white cumulus floating in its widest sky, a third of the sky's
            height above the skyline (unchanged where the sky is under 60 px
            per 1000 columns high); ring-sky-cloud: the ring on those copies
  occluder  (not in the default set; seconds) plain on each photo with a
            dark conifer and a power pole rising from the bottom edge into
            its sky (at 22% and 68% of the width, their tops half and two
            thirds of the sky's height above the skyline): near objects at a
            viewpoint hide part of the skyline (--floors occluder=N);
            ring-occluder: the ring on those copies
  cables    (not in the default set; seconds) plain on each photo with two
            dark power cables sagging across its whole width, 2 px thick per
            1000 columns, their ends at 35% and 60% of the median sky height
            above the skyline (--floors cables=N); ring-cables: the ring on
            those copies
  contrails (not in the default set; seconds) plain on each photo with
            two white aircraft contrails across its sky, a fresh one
            (Gaussian sigma 2.5 px per 1000 columns, 75% opacity) and a
            spread one (9 px, 35%), rising from 70% to 25% and from 40% to
            15% of the median sky height above the skyline, never within
            3 px of it (--floors contrails=N); ring-contrails: the ring on
            those copies
  sun       (not in the default set; seconds) plain on each photo with the
            sun low over a ridge at 70% of the width: a clipped disc, a warm
            glow veiling the ridge under it and three flare rings (--floors
            sun=N); ring-sun: the ring on those copies
  roof      (not in the default set; seconds) plain on each photo with a
            hut's gable in the foreground, its ridge half the sky's height
            above the skyline at 15% of the width, its eaves from the left
            edge to 32% of it: a third of the skyline hidden behind
            straight edges no DEM has (--floors roof=N); ring-roof: the ring
            on those copies
  turned    (not in the default set; seconds) plain on each photo stored a
            quarter turn anticlockwise with EXIF Orientation 6 and its
            recorded size the stored pixels' (a camera held upright): decoded
            upright, it must register as the photo does, and is not taken
            for a crop (--floors turned=N)
  crop      (not in the default set; seconds) plain on each photo cropped
            to 3/4 of its width (the left part for every other photo, the
            right for the rest; JPEG quality 95, EXIF kept: its recorded size
            no longer the photo's shape, as a photographer's crop leaves it).
            The truth is the ray through the crop's centre by the author's
            full camera model. Counts the photos within 0.5 deg (--floors
            crop=N) and the false ones (0)
  tilted    (not in the default set; seconds) plain on each photo turned by
            +6 and by -6 deg about its centre (a camera held askew) and cut
            to the largest centred frame of its shape inside the turned one
            (PNG, no EXIF: --hfov from the truth, the cut frame's opening
            angle). Rows, cliffs and ridges then leave the frame through its
            top corner and the frame's top edge cuts them. The truth: the ray
            through the cut frame's centre by the author's camera model, the
            roll turned by the angle. Counts the copies within 0.5 deg
            (--floors tilted=N, of 26) and the false ones (0)
  wrong-tilted, ring-tilted  (not in the default set) the wrong probes and
            the ring's 468 on those copies (+6 deg for every other photo,
            -6 for the rest; --floors ring-tilted=N, a ceiling, default 0)
  stations  (not in the default set; seconds) `batch` over every photo, its
            JPEG quality 95 copy and its pixels alone (PNG, no EXIF), the
            photos of a station (one position) in one run, with and without
            --check-every-photo: once two photos of a station have passed
            the position check (and none was refused), the rest skip its wide
            look, and one with no opening angle of its own that found no pose
            is tried again within the station camera's. Per photo the status
            and error both ways; fails when a decision or pose differs
            between the two runs (but for those registered within the
            station's opening angle) or a registration is false, or below
            --floors stations=N (photos and copies within 0.5 deg)
  wrong-stations  (not in the default set) every station's batch (photos and
            copies) from the wrong probes' positions and the other regions'
            DEMs: none may register more than 1 deg off (as the ring's probes)
  ring-stations  (not in the default set) the same from the ring's positions
  batch-equals  (not in the default set) the wrong probes registered one by
            one with `register` and through `batch --check-every-photo` (as
            every probe mode runs them: one process per DEM, a third of the
            CPU time): fails on any row whose status, message, pose, opening
            angle, ambiguity, inlier fraction or evidence differs
  crop-narrow  (not in the default set; seconds) the same with the centre
            half of the width (a portrait frame cut from a landscape photo:
            not turned, its height whole; --floors crop-narrow=N)
  wrong-crop, wrong-crop-narrow  (not in the default set) the wrong probes
            on those crops
  ring-crop, ring-crop-narrow  (not in the default set; about 2 minutes)
            the ring of wrong positions (ring's 468 probes) on those crops:
            a narrower view tells a wrong position from the true one less
            well (README); with --check, fails when the false ones exceed
            --floors ring-crop=N, ring-crop-narrow=N (ceilings, default 0)
  reencode  (not in the default set) plain on each photo decoded and saved
            again as JPEG at quality 95 with its EXIF segment kept: the
            pixels change by ~0.2 grey levels on average (an upload, an
            export); the registration should not. Counts the photos within
            0.5 deg (--floors reencode=N, default 0) and the false ones (0)
  gray      (not in the default set) plain on each photo turned to grey
            (luma, saved as JPEG quality 95 with its EXIF segment kept): a
            black-and-white archive print or a monochrome webcam, with no
            chroma to tell blue sky from white snow. Counts the photos within
            0.5 deg (--floors gray=N, default 0) and the false ones (0)
  upscale2, upscale4  (not in the default set) plain on each photo
            upscaled 2x or 4x (bicubic, JPEG quality 95, EXIF kept): the
            pixel count of a phone's or a DSLR's photo, whose edges spread
            over more rows than the archive's reduced copies. Counts the photos
            within 0.5 deg (--floors upscale2=N, upscale4=N, default 0) and the
            false ones (0)
  wrong-upscale4  (not in the default set) the wrong probes on the 4x copies
  downscale2  (not in the default set) plain on each photo at half its size
            (area averaging, JPEG quality 95, EXIF kept): a web page's or a
            webcam's 360-540 columns, where each pixel spans twice the angle.
            Counts the photos within 0.5 deg (--floors downscale2=N, default
            0) and the false ones (0)
  wrong-downscale2  (not in the default set) the wrong probes on those copies
  jpeg50, jpeg30  (not in the default set) plain on each photo re-encoded
            as JPEG at quality 50 or 30 (EXIF kept): a webcam's or a web
            page's copy, whose smooth sky comes in flat 8 x 8 blocks and
            16 x 16 chroma blocks with steps between them. Counts the photos
            within 0.5 deg (--floors jpeg50=N, jpeg30=N, default 0) and the
            false ones (0)
  wrong-jpeg30  (not in the default set) the wrong probes on the quality-30
            copies
  wrong-occluder, wrong-cables, wrong-contrails, wrong-sun, wrong-roof
            (not in the default set) the wrong probes (2-10 km, other
            regions' DEMs) on the occluder, cable, contrail, sun and roof
            copies
  photometric  (not in the default set; about 2 minutes) plain on each photo
            changed as another camera, exposure or weather would change it:
            1.7 stops darker, 1.3 stops brighter (clipped), sensor noise,
            soft focus, vignetting, a warm and a cool white balance, a grey
            veil, a thick veil, an overcast sky's grey light (JPEG quality
            95, EXIF kept). Per change: the photos within 0.5 deg (--floors
            photometric=N, each change, or photometric-KEY=N for change KEY;
            default 0), the
            false ones (0) and the skyline's traced columns within 2 px
            (over all changes: --floors photometric-skyline=W, default 0)
  wrong-photometric  (not in the default set; minutes) the wrong probes on
            every photometric copy
  ring-noise, ring-blur, ring-dark, ... (ring-KEY for each photometric
            change; not in the default set; minutes each) the ring's 468
            wrong positions on that change's copies: registered and false
            (> 1 deg; --floors ring-KEY=N, a ceiling, default 0); so too
            ring-reencode, ring-gray, ring-upscale2,
            ring-upscale4, ring-downscale2, ring-jpeg50, ring-jpeg30,
            ring-banner, ring-turned, ring-cloud, ring-cloud-small,
            ring-sky-cloud on those modes' copies
  jpeg30-skyline  (not in the default set; seconds) the skyline of the
            quality-30 copies against the hand trace, as skyline (--floors
            jpeg30-skyline=F)
  stability  (not in the default set; seconds) how far each photo's extracted
            skyline moves when the photo is re-encoded as JPEG at quality 95
            (pixels change by ~0.2 grey levels) or 50: per photo the columns
            given a value in both, those that move by more than 1 and 3 px,
            and those given in one only. Hand trace not needed: all photos.
            A skyline that moves with such noise decides some columns on a
            threshold's edge; the registration then moves with it (reencode
            registers 10 of 13). With --check, fails when the share of the
            columns moving more than 1 px exceeds --floors stability=F (a
            ceiling, default 1: no check)
  gray-skyline  (not in the default set; seconds) the skyline of the grey
            copies against the hand trace, as skyline (--floors
            gray-skyline=F, a share of the traced columns within 2 px)
  ring      (not in the default set; about 1 minute) register from a ring of
            wrong positions, 12 bearings (every 30 deg) at 2, 3 and 5 km:
            wrong's 5 offsets sample a few bearings, and from a position 2-3 km
            off, sideways to a far range 15-30 km away, the parallax between its
            nearer and farther peaks is nearly absorbed by the opening angle,
            pitch and roll. Counts registrations (all should be no_match) and
            false ones (> 1 deg off in azimuth or pitch); with --check, fails
            when the false ones exceed --floors ring=N (a ceiling, default 0)
  ring-camera  (not in the default set) the same ring with --camera from the
            truth (--floors ring-camera=N)
  ring-initial  (not in the default set) the same ring with --initial 2 deg
            off the truth, as wrong-initial (--floors ring-initial=N)
  ring-noexif  (not in the default set) the same ring with --no-exif: the
            opening angle unknown, 10-120 deg searched (a webcam frame or a
            stripped upload given the wrong coordinates; --floors
            ring-noexif=N)
  sensors   (not in the default set) --sensors files reading the truth 2 deg
            off (as initial's four offsets; a compass prior of 15 deg, an
            inclinometer of 2): runs within 0.5 deg and photos registered
            from all four (--floors sensors=N)
  ring-sensors  (not in the default set) the same ring with --sensors: a
            compass and inclinometer reading the truth 2 deg off (priors of
            15 and 2 deg; --floors ring-sensors=N)
  perturbed (not in the default set; about 2 minutes) plain and wrong again
            under 6 harmless changes of the horizon's sampling (--step 0.08,
            0.09, 0.12, 0.125) and refraction (--refraction 0.10, 0.16) as
            well as the defaults: how often each photo registers, and how
            near the wrong probes come to the ambiguity gate. One run per
            photo tells a photo whose cost ratio sits at the gate from one
            far above it only by luck; this tells them apart.
Usage: eval_real.py HORIZONREG SHARED_DIR [--modes plain,camera,...] [--check]
       [--overlay-dir DIR] [--only NAME,...] [--jobs N]
With --check, exits 1 when a figure misses the floor it is checked against
(--floors plain=12,camera=12,initial=13,skyline=0.9,thin=0.9,skyline-given=0.95,
thin-given=0.95 by default: skyline and thin are within 2 px, the -given floors
the share given a value: the issue's targets) or when any registration is
false.
"""
import collections, concurrent.futures, hashlib, json, math, os, statistics, subprocess, sys, tempfile

ALL_MODES = ["plain", "camera", "initial", "traced", "traced-pinhole", "skyline", "registered-skyline", "thin", "wrong",
             "wrong-camera", "wrong-initial"]
THIN_SKY_PX = 10  # the thin mode's sky left above the traced horizon's highest point
# Positions 2-10 km away (bearing deg, distance m) and other regions' DEMs
# (with a position inside each), for the false-registration probes.
WRONG_OFFSETS = [(0, 2000), (120, 3000), (240, 5000), (60, 7000), (300, 10000)]
RING_OFFSETS = [(b, d) for d in (2000, 3000, 5000) for b in range(0, 360, 30)]  # the ring mode's
OTHER_DEMS = [("mt_rainier_90m.tif", 46.80, -121.73), ("N47E009.hgt", 47.25, 9.35)]
# The perturbed mode's changes: none should change the answer.
PERTURBATIONS = [[], ["--step", "0.08"], ["--step", "0.09"], ["--step", "0.12"], ["--step", "0.125"],
                 ["--refraction", "0.10"], ["--refraction", "0.16"]]
INITIAL_OFFSETS = [(2, 0), (-2, 0), (0, 2), (0, -2)]  # --initial: degrees off the truth in azimuth, pitch
GATE_RATIO = 1.4  # RegistrationOptions::min_ambiguity_ratio, for the near-miss count


def angdiff(a, b):
    return (a - b + 180.0) % 360.0 - 180.0


def offset_position(lat, lon, bearing_deg, dist_m):
    r = 6371000.0
    b = math.radians(bearing_deg)
    dlat = dist_m * math.cos(b) / r
    dlon = dist_m * math.sin(b) / (r * math.cos(math.radians(lat)))
    return lat + math.degrees(dlat), lon + math.degrees(dlon)


def false_probe_list(photos, shared):
    """The false-registration probes of each photo: (photo, label, dem, lat,
    lon) from WRONG_OFFSETS (its own DEM: dem None, the altitude given) and
    inside OTHER_DEMS present (dem named, no altitude)."""
    probes = []
    for p in photos:
        for bearing, dist in WRONG_OFFSETS:
            lat, lon = offset_position(p[1]["lat"], p[1]["lon"], bearing, dist)
            probes.append((p, f"{dist / 1000:.0f} km at {bearing}", None, lat, lon))
        for dem, lat, lon in OTHER_DEMS:
            if os.path.exists(os.path.join(shared, "dem", dem)):
                probes.append((p, dem, dem, lat, lon))
    return probes


def probe_call(probe, extra=(), image=None, truth=None):
    """register's keyword arguments (register_many's call) for a false
    probe of false_probe_list, on `image` (a copy, else the photo) with the
    truth `truth` (a crop's, else the photo's)."""
    (name, t, d), _, dem, lat, lon = probe
    return dict(photo_dir=d, name=name, truth=truth or t, extra=list(extra), dem=dem, lat=lat, lon=lon,
                alt=dem is None, image=image)


def probe_rows(binary, shared, probes, calls, jobs, tmpdir):
    """(photo, label, row) of each false probe, registered with its call."""
    return [(pr[0][0], pr[1], r) for pr, r in zip(probes, register_many(binary, shared, calls, jobs, tmpdir))]


def report_wrong(title, out):
    """Prints the probes' (name, label, report) that registered or failed;
    True when none did."""
    print(f"\n== {title}: all must be no_match ==")
    bad = [(n, l) for n, l, r in out if r.get("status") == "registered"]
    errs = [(n, l, r.get("message")) for n, l, r in out if r.get("status") == "error"]
    for n, l in bad:
        print(f"  FALSE REGISTRATION: {n} from {l}")
    for n, l, m in errs:
        print(f"  error: {n} from {l}: {m}")
    print(f"probes: {len(out)}; registered (false): {len(bad)}; errors: {len(errs)}")
    return not bad and not errs


def register(binary, shared, photo_dir, name, truth, extra, dem=None, lat=None, lon=None, alt=True, overlay=None,
             image=None):
    with tempfile.NamedTemporaryFile(suffix=".json") as tmp:
        cmd = [binary, "register", image or os.path.join(photo_dir, truth["image"]),
               "--dem", os.path.join(shared, "dem", dem or truth["dem"]),
               "--lat", repr(truth["lat"] if lat is None else lat), "--lon", repr(truth["lon"] if lon is None else lon),
               "--json", tmp.name] + extra
        cmd += ["--alt", repr(truth["alt_m"])] if alt else ["--agl", "2"]
        if overlay:
            cmd += ["--overlay", overlay]
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            return {"status": "error", "message": p.stderr.strip()[:120], "stderr": p.stderr}
        r = json.load(open(tmp.name))
        r["stderr"] = p.stderr
        return r


def batch_rows(binary, shared, dem, rows, extra, stem):
    """`batch` over a JSON manifest of `rows` (dicts: image, lat, lon,
    alt_m or agl_m, ...) against SHARED/dem/DEM with the options `extra`, on
    one thread; files STEM.json and STEM.jsonl. Returns ({image: row}, the
    finished process)."""
    manifest, out = stem + ".json", stem + ".jsonl"
    json.dump(rows, open(manifest, "w"))
    if os.path.exists(out):
        os.remove(out)
    p = subprocess.run([binary, "batch", manifest, "--dem", os.path.join(shared, "dem", dem), "-o", out,
                        "--threads", "1", "--no-progress"] + list(extra), capture_output=True, text=True)
    got = {r["image"]: r for r in map(json.loads, open(out))} if os.path.exists(out) else {}
    return got, p


def register_many(binary, shared, calls, jobs, tmpdir):
    """What register(binary, shared, **call) answers for each call (a dict of
    register's keyword arguments), in order, through `batch
    --check-every-photo`: every row registered on its own, the position
    check's wide look included, as `register` does (batch-equals compares
    the two on the wrong probes; cli/batch_equals_register on the true
    positions). One process per DEM and set of whole-run options, split in
    `jobs` parts run side by side: a process pays its start (about 0.15 s:
    160 shared libraries) and its first DEM once instead of once per probe,
    which made the probes a third of the CPU time. --camera, --sensors,
    --hfov and --initial become the manifest's columns; each row reads its
    image through its own link (a manifest lists an image once)."""
    per_row = {"--camera": "camera", "--sensors": "sensors", "--hfov": "hfov_deg"}
    groups = collections.defaultdict(list)
    for ix, c in enumerate(calls):
        t = c["truth"]
        row = {"lat": t["lat"] if c.get("lat") is None else c["lat"],
               "lon": t["lon"] if c.get("lon") is None else c["lon"]}
        if c.get("alt", True):
            row["alt_m"] = t["alt_m"]
        else:
            row["agl_m"] = 2
        extra, whole, k = list(c.get("extra") or []), [], 0
        while k < len(extra):
            if extra[k] in per_row:
                row[per_row[extra[k]]] = extra[k + 1]
                k += 1
            elif extra[k].startswith("--initial="):
                row["initial"] = extra[k].partition("=")[2]
            else:
                whole.append(extra[k])
            k += 1
        image = c.get("image") or os.path.join(c["photo_dir"], t["image"])
        groups[(c.get("dem") or t["dem"], tuple(whole))].append((ix, image, row))
    parts = [(f"{g}.{j}", dem, whole, members[j::jobs])
             for g, ((dem, whole), members) in enumerate(sorted(groups.items())) for j in range(jobs)
             if members[j::jobs]]
    results = [None] * len(calls)

    def run(part):
        key, dem, whole, share = part
        folder = os.path.join(tmpdir, "batch." + key)
        os.makedirs(folder, exist_ok=True)
        rows, index = [], {}
        for ix, image, row in share:
            link = os.path.join(folder, f"{ix}{os.path.splitext(image)[1]}")
            if os.path.lexists(link):
                os.remove(link)
            os.symlink(os.path.abspath(image), link)
            rows.append(dict(row, image=link))
            index[link] = ix
        got, p = batch_rows(binary, shared, dem, rows, ["--check-every-photo"] + list(whole),
                            os.path.join(folder, "manifest"))
        for link, ix in index.items():
            r = got.get(link)
            if r is None:
                r = {"status": "error", "message": f"batch (exit {p.returncode}) gave no row: {p.stderr.strip()[:120]}"}
            results[ix] = r
    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        list(pool.map(run, parts))
    return results


def opencv_for(mode):
    """OpenCV's Python module (python3-opencv, a test dependency: only some
    modes need it), or None after saying which mode lacks it."""
    try:
        import cv2
        return cv2
    except ImportError:
        print(f"FAIL: --modes {mode} needs OpenCV's Python module: python3-opencv (make test-deps), "
              "with Debian's /usr/bin/python3")
        return None


def with_exif_of(original, jpeg):
    """`jpeg` (bytes) with the APP1 (EXIF) segments of `original` inserted
    after its start-of-image marker (both JPEG files)."""
    segments, i = [], 2
    while i + 4 <= len(original) and original[i] == 0xFF and original[i + 1] not in (0xDA, 0xD9):
        length = int.from_bytes(original[i + 2:i + 4], "big")
        if original[i + 1] == 0xE1:
            segments.append(original[i:i + 2 + length])
        i += 2 + length
    return jpeg[:2] + b"".join(segments) + jpeg[2:]


def camera_file(truth, path):
    c = truth["camera"]
    json.dump({"fx_px": c["fx_px"], "fy_px": c["fy_px"], "cx_px": c["cx_px"], "cy_px": c["cy_px"],
               "k": c["k"], "p": c["p"], "width": truth["width"], "height": truth["height"]}, open(path, "w"))


def camera_files(photos, tmpdir):
    """Each photo's camera file, written once, before probes that read it run
    side by side (a probe writing it while another read it saw it half
    written). Returns {name: path}."""
    paths = {}
    for name, t, _ in photos:
        paths[name] = os.path.join(tmpdir, name + ".camera.json")
        camera_file(t, paths[name])
    return paths


def sensors_files(photos, tmpdir):
    """Per photo and INITIAL_OFFSETS entry, a --sensors file: a compass and
    an inclinometer reading the truth that far off (a phone's or a
    station's sensors). Returns {(name, i): path}."""
    paths = {}
    for name, t, _ in photos:
        for i, (daz, dp) in enumerate(INITIAL_OFFSETS):
            paths[(name, i)] = os.path.join(tmpdir, f"{name}.{i}.sensors.json")
            json.dump({"compass_yaw_deg": t["yaw_deg"] + daz, "inclinometer_pitch_deg": t["pitch_deg"] + dp,
                       "inclinometer_roll_deg": t["roll_deg"]}, open(paths[(name, i)], "w"))
    return paths


# Variants of the probe runs: how each names itself in a table's title, the
# arguments it adds (variant_args) and the files those read (variant_files).
VARIANT_TITLES = {"": "", "camera": " with --camera", "initial": " with --initial 2 deg off the truth",
                  "sensors": " with --sensors 2 deg off the truth", "noexif": " with --no-exif",
                  "hfov": " with --hfov from the truth",
                  "range": " with --hfov-range +-20% around the truth",
                  "noalt": " without the altitude (--agl 2: the eye 2 m above the DEM there)",
                  "noalt-hfov": " without the altitude (--agl 2) and with --hfov from the truth"}


def variant_files(variant, photos, tmpdir):
    """The camera or sensors files a variant's runs read, written before they run."""
    if variant == "camera":
        return camera_files(photos, tmpdir)
    return sensors_files(photos, tmpdir) if variant == "sensors" else {}


def variant_args(variant, name, t, i, files):
    """The arguments run i of photo `name` (truth t) adds under `variant`:
    the truth's camera; the truth 2 deg off as --initial or as sensors
    (INITIAL_OFFSETS in turn); no EXIF."""
    daz, dp = INITIAL_OFFSETS[i % len(INITIAL_OFFSETS)]
    if variant == "camera":
        return ["--camera", files[name]]
    if variant == "initial":
        return [f"--initial={t['yaw_deg'] + daz},{t['pitch_deg'] + dp},{t['roll_deg']},{t['hfov_deg']}"]
    if variant == "sensors":
        return ["--sensors", files[(name, i % len(INITIAL_OFFSETS))]]
    if variant in ("hfov", "noalt-hfov"):
        return ["--hfov", repr(t["hfov_deg"])]
    if variant == "range":
        return ["--hfov-range", f"{0.8 * t['hfov_deg']:.2f}:{1.2 * t['hfov_deg']:.2f}"]
    return ["--no-exif"] if variant == "noexif" else []


def write_jpeg_with_exif(cv2, image, source, path, quality=95):
    """`image` written to `path` as JPEG with the EXIF of the photo `source`
    kept; False when OpenCV cannot encode it."""
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if ok:
        with open(path, "wb") as f:
            f.write(with_exif_of(open(source, "rb").read(), data.tobytes()))
    return ok


def ray_through(cv2, truth, u, v):
    """Azimuth and elevation (degrees) of the ray through pixel (u, v) (the
    origin at the top-left corner of the top-left pixel) by the truth's full
    camera model: its intrinsics and distortion, its optical axis and roll
    (right side down positive)."""
    import numpy as np
    c = truth["camera"]
    k = list(c["k"]) + [0.0] * (6 - len(c["k"]))
    matrix = np.array([[c["fx_px"], 0, c["cx_px"]], [0, c["fy_px"], c["cy_px"]], [0, 0, 1]], float)
    dist = np.array([k[0], k[1], c["p"][0], c["p"][1], k[2], k[3], k[4], k[5]], float)
    x, y = cv2.undistortPointsIter(np.array([[[u, v]]], float), matrix, dist, None, None,
                                   (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))[0, 0]
    az, p, r = (math.radians(a) for a in (c["axis_yaw_deg"], c["axis_pitch_deg"], truth["roll_deg"]))
    forward = np.array([math.sin(az) * math.cos(p), math.cos(az) * math.cos(p), math.sin(p)])
    right = np.array([math.cos(az), -math.sin(az), 0.0])
    down = -np.cross(right, forward)
    d = x * (math.cos(r) * right + math.sin(r) * down) + y * (math.cos(r) * down - math.sin(r) * right) + forward
    d /= np.linalg.norm(d)
    return math.degrees(math.atan2(d[0], d[1])) % 360.0, math.degrees(math.asin(d[2]))


def cropped_copy(cv2, truth, source, path, where, share):
    """The photo cropped to `share` of its width (its "left", "right" or
    "centre" part), JPEG quality 95 with its EXIF kept, and the truth of the
    crop: the ray through its centre, its opening angle. None when it cannot
    be written."""
    image = cv2.imread(source)
    h, w = image.shape[:2]
    kept = int(round(w * share))
    x0 = {"left": 0, "right": w - kept, "centre": (w - kept) // 2}[where]
    if not write_jpeg_with_exif(cv2, image[:, x0:x0 + kept], source, path):
        return None
    t = dict(truth)
    t["yaw_deg"], t["pitch_deg"] = ray_through(cv2, truth, x0 + kept / 2.0, h / 2.0)
    t["hfov_deg"] = math.degrees(2.0 * math.atan(kept / (2.0 * truth["camera"]["fx_px"])))
    return t


TILT_DEG = 6.0  # the tilted modes' turn, both ways


def tilted_copy(cv2, truth, source, path, angle_deg):
    """The photo turned by `angle_deg` about its centre (anticlockwise
    positive: the camera's right side down, its roll grows by the angle) and
    cut to the largest centred frame of its shape inside the turned one,
    written as PNG (no EXIF), and the truth of the copy: the ray through its
    centre, its roll and opening angle, its size. None when it cannot be
    written."""
    import numpy as np
    image = cv2.imread(source)
    h, w = image.shape[:2]
    th = math.radians(abs(angle_deg))
    scale = min(1.0, 1.0 / (math.cos(th) + (w / h) * math.sin(th)), 1.0 / (math.cos(th) + (h / w) * math.sin(th)))
    cw, ch = int(w * scale) // 2 * 2, int(h * scale) // 2 * 2
    x0, y0 = (w - cw) // 2, (h - ch) // 2
    m = cv2.getRotationMatrix2D((w / 2.0, h / 2.0), angle_deg, 1.0)
    turned = cv2.warpAffine(image, m, (w, h), flags=cv2.INTER_LINEAR)
    if not cv2.imwrite(path, turned[y0:y0 + ch, x0:x0 + cw]):
        return None
    # The cut frame's centre, back in the photo's pixels.
    inverse = cv2.invertAffineTransform(m)
    u, v = inverse @ np.array([x0 + cw / 2.0, y0 + ch / 2.0, 1.0])
    t = dict(truth)
    t["yaw_deg"], t["pitch_deg"] = ray_through(cv2, truth, float(u), float(v))
    t["roll_deg"] = truth["roll_deg"] + angle_deg
    t["hfov_deg"] = math.degrees(2.0 * math.atan(cw / (2.0 * truth["camera"]["fx_px"])))
    t["width"], t["height"] = cw, ch
    t["skyline_row"] = [None] * cw
    return t


def blend_cloud(cv2, image, mask, blur_px, opacity, bgr):
    """`image` under a cloud of colour `bgr` where `mask` (float, 1 inside
    the cloud's ellipses) lies: the mask blurred by a Gaussian of `blur_px`,
    raised by 1.3 and capped at `opacity`, as the blend's weight."""
    import numpy as np
    weight = np.clip(cv2.GaussianBlur(mask, (0, 0), blur_px) * 1.3, 0, opacity)[..., None]
    out = image.astype(np.float32) * (1 - weight) + np.array(bgr, np.float32) * weight
    return np.clip(out, 0, 255).astype(np.uint8)


def cap_cloud(cv2, image, rows, share=0.2, seed=0):
    """A cap cloud resting on the photo's highest stretch of skyline (`rows`:
    the skyline row per column, None where unknown): fourteen soft white
    ellipses over `share` of the width, from a fixed seed, blurred and
    blended at up to 97% opacity, hiding the summit and the slopes beside
    it (the boundary under it is not the terrain's)."""
    import numpy as np
    h, w = image.shape[:2]
    s = w / 1000.0
    ys = np.array([np.nan if v is None else float(v) for v in rows])
    k = max(1, int(share * w))
    mean = np.convolve(np.nan_to_num(ys, nan=1e9), np.ones(k) / k, "valid")
    x0 = int(np.argmin(mean))
    xc, yc = x0 + k // 2, float(np.nanmin(ys[x0:x0 + k]))
    rng = np.random.default_rng(seed)
    mask = np.zeros((h, w), np.float32)
    for _ in range(14):
        cx, cy = xc + rng.uniform(-0.45, 0.45) * k, yc + rng.uniform(-10, 40) * s
        ax, ay = rng.uniform(0.12, 0.25) * k, rng.uniform(15, 35) * s
        cv2.ellipse(mask, (int(cx), int(cy)), (int(ax), int(ay)), 0, 0, 360, 1.0, -1)
    return blend_cloud(cv2, image, mask, 6 * s, 0.97, (238, 238, 236))


def sky_cloud(cv2, image, rows, share=0.25):
    """A white cumulus floating in the sky over the stretch of `share` of the
    width with the most sky above its highest skyline point (`rows`: the
    skyline row per column, None where unknown): seven overlapping ellipses
    in a fixed pattern (src/skyline/skyline_test.cc paints the same), blurred
    and blended at up to 95% opacity, their base a third of that sky's height
    above the skyline (at least 20 px per 1000 columns). None when that sky is
    under 60 px per 1000 columns high: no room for a cloud."""
    import numpy as np
    h, w = image.shape[:2]
    s = w / 1000.0
    k = max(1, int(share * w))
    best, x0 = -1.0, 0
    for x in range(0, w - k + 1):
        known = [float(v) for v in rows[x:x + k] if v is not None]
        if known and min(known) > best:
            best, x0 = min(known), x
    if not best >= 60 * s:
        return None
    base = best - max(20 * s, best / 3.0)
    thick = min(36 * s, 0.5 * base)
    mask = np.zeros((h, w), np.float32)
    for i in range(7):
        cx = x0 + k / 2 + (i - 3) / 3.0 * 0.35 * k
        cy = base - thick / 2 + (0.15 if i % 2 else -0.1) * thick
        cv2.ellipse(mask, (int(cx), int(cy)), (int(0.16 * k), int(0.4 * thick)), 0, 0, 360, 1.0, -1)
    return blend_cloud(cv2, image, mask, 4 * s, 0.95, (240, 240, 238))


def occluders(cv2, image, rows):
    """Two near objects standing into the sky, as at a viewpoint: a conifer
    (dark green, nine jagged tiers, 90 px wide per 1000 columns at the
    bottom edge) from the bottom edge at 22% of the width, its top half the sky's
    height above the skyline there (`rows`: the skyline row per column, None
    where unknown), and a power pole (dark grey, 6 px per 1000 columns, a
    crossarm 44 px wide) at 68%, its top two thirds of that sky above it;
    both at least 4 px below the photo's top. The skyline behind them is
    hidden; no other column changes."""
    import numpy as np
    h, w = image.shape[:2]
    s = w / 1000.0
    out = image.copy()

    def sky_above(xc):
        known = [(abs(x - xc), float(v)) for x, v in enumerate(rows) if v is not None]
        return min(known)[1] if known else h / 2.0

    xt = int(0.22 * w)
    top = max(4.0, sky_above(xt) * 0.5)
    half = 45 * s
    tiers = 9
    pts_l, pts_r = [], []
    for i in range(1, tiers + 1):  # each tier: out to its tip, then back in
        y = top + (h - top) * i / tiers
        wdt = half * i / tiers
        pts_l += [(xt - wdt, y), (xt - 0.55 * wdt, y)]
        pts_r += [(xt + wdt, y), (xt + 0.55 * wdt, y)]
    poly = [(xt, top)] + pts_r + pts_l[::-1]
    cv2.fillPoly(out, [np.array(poly, np.int32)], (28, 52, 30), cv2.LINE_AA)
    xp = int(0.68 * w)
    ptop = max(4.0, sky_above(xp) / 3.0)
    cv2.rectangle(out, (int(xp - 3 * s), int(ptop)), (int(xp + 3 * s), h), (48, 50, 52), -1)
    cv2.rectangle(out, (int(xp - 22 * s), int(ptop + 10 * s)), (int(xp + 22 * s), int(ptop + 14 * s)),
                  (48, 50, 52), -1)
    return out


def cables(cv2, image, rows):
    """Two power cables sagging across the whole width of the sky, dark
    grey, 2 px thick per 1000 columns (anti-aliased): their ends at 35% and
    60% of the median sky height above the skyline (`rows`: the skyline row
    per column, None where unknown), sagging by 15% of it at the middle.
    Where the sky is thin they cross the terrain, as cables do."""
    import numpy as np
    h, w = image.shape[:2]
    s = w / 1000.0
    known = [float(v) for v in rows if v is not None]
    sky = float(np.median(known)) if known else h / 2.0
    out = image.copy()
    xs = np.arange(w, dtype=np.float64)
    for share in (0.35, 0.6):
        ys = sky * share + 0.15 * sky * (1.0 - ((xs - w / 2.0) / (w / 2.0)) ** 2)
        cv2.polylines(out, [np.stack([xs, ys], 1).astype(np.int32)], False, (40, 40, 40),
                      max(1, int(round(2 * s))), cv2.LINE_AA)
    return out


def contrails(cv2, image, rows):
    """Two aircraft contrails across the sky, as over the Alps on most clear
    days: straight, white, soft-edged (a fresh one, Gaussian core 2.5 px
    sigma per 1000 columns at up to 75% opacity, and an older one spread to
    9 px at 35%), rising across the width from 70% to 25% and from 40% to
    15% of the median sky height above the skyline (`rows`: the skyline row
    per column, None where unknown). Contrails are far above any ridge: no
    terrain pixel within 3 px of the skyline changes (the skyline taken
    across untraced columns from the traced ones either side)."""
    import numpy as np
    h, w = image.shape[:2]
    s = w / 1000.0
    known = [float(v) for v in rows if v is not None]
    sky = float(np.median(known)) if known else h / 2.0
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    alpha = np.zeros((h, w))
    for a, b, sigma, opacity in ((0.7, 0.25, 2.5, 0.75), (0.4, 0.15, 9.0, 0.35)):
        line = sky * a + (sky * b - sky * a) * xx / (w - 1)
        alpha = np.maximum(alpha, opacity * np.exp(-0.5 * ((yy - line) / (sigma * s)) ** 2))
    xs = [x for x, v in enumerate(rows) if v is not None]
    top = (np.interp(np.arange(w), xs, [float(rows[x]) for x in xs]) if xs else np.full(w, float(h))) - 3.0
    alpha[yy >= top[None, :]] = 0.0
    white = np.array([250.0, 250.0, 248.0])
    out = image.astype(np.float64) * (1.0 - alpha[..., None]) + white * alpha[..., None]
    return np.clip(out + 0.5, 0, 255).astype(np.uint8)


def sun_glare(cv2, image, rows):
    """The sun low over a ridge, as in an evening photo against the light: a
    clipped white disc (radius 1.5% of the width) centred its own diameter
    above the skyline at 70% of the width (`rows`: the skyline row per
    column, None where unknown), in a warm glow that falls off as
    exp(-r / 6% of the width) and veils the ridge under it, and three flare
    rings along the line through the image centre."""
    import numpy as np
    h, w = image.shape[:2]
    xs = int(0.7 * w)
    near = [(abs(x - xs), float(v)) for x, v in enumerate(rows) if v is not None]
    ys = (min(near)[1] if near else h / 2.0) - 0.03 * w
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    r = np.hypot(xx - xs, yy - ys)
    glow = np.exp(-r / (0.06 * w))
    glow[r <= 0.015 * w] = 1.0
    out = image.astype(np.float64)
    warm = np.array([235.0, 250.0, 255.0])  # BGR
    out = out * (1.0 - 0.95 * glow[..., None]) + warm * 0.95 * glow[..., None]
    cx, cy = w / 2.0, h / 2.0
    for t, radius, strength in ((0.5, 0.02, 0.25), (1.3, 0.035, 0.18), (1.7, 0.012, 0.3)):
        fx, fy = cx + (cx - xs) * t, cy + (cy - ys) * t
        ring = np.exp(-np.hypot(xx - fx, yy - fy) / (radius * w)) * strength
        out = out * (1.0 - ring[..., None]) + np.array([200.0, 255.0, 230.0]) * ring[..., None]
    return np.clip(out + 0.5, 0, 255).astype(np.uint8)


def roof(cv2, image, rows):
    """A hut's roof in the foreground, as from a terrace: a dark brown
    gable whose ridge stands half the sky's height above the skyline at 15%
    of the width (`rows`: the skyline row per column, None where unknown),
    its slopes falling 0.6 px per column to eaves past the left edge and at
    32% of the width, its walls down to the bottom edge, a chimney on its
    right slope: a third of the skyline hidden behind straight edges no
    DEM has."""
    import numpy as np
    h, w = image.shape[:2]
    xs = [x for x, v in enumerate(rows) if v is not None]
    sky = float(np.interp(0.15 * w, xs, [float(rows[x]) for x in xs])) if xs else h / 2.0
    peak = (0.15 * w, max(4.0, 0.5 * sky))
    out = image.copy()
    poly = np.array([(-0.02 * w, h), (-0.02 * w, peak[1] + 0.17 * w * 0.6), peak,
                     (0.32 * w, peak[1] + 0.17 * w * 0.6), (0.32 * w, h)], np.int32)
    cv2.fillPoly(out, [poly], (30, 45, 70), cv2.LINE_AA)
    cx = 0.24 * w
    cy = peak[1] + (cx - peak[0]) * 0.6
    cv2.rectangle(out, (int(cx), int(cy - 0.03 * w)), (int(cx + 0.025 * w), int(cy + 0.02 * w)), (40, 40, 48), -1)
    return out


def turned_copy(cv2, source, path):
    """The photo stored a quarter turn anticlockwise with EXIF Orientation 6
    (turn clockwise to show) and its recorded size the stored pixels', as a
    camera held upright writes it: decoded upright it is the photo again.
    False when its EXIF lacks the tags to rewrite."""
    import struct
    stored = cv2.rotate(cv2.imread(source), cv2.ROTATE_90_COUNTERCLOCKWISE)
    ok, data = cv2.imencode(".jpg", stored, [cv2.IMWRITE_JPEG_QUALITY, 95])
    if not ok:
        return False
    out = bytearray(with_exif_of(open(source, "rb").read(), data.tobytes()))
    base = out.find(b"Exif\x00\x00") + 6
    if base < 6:
        return False
    order = "<" if out[base:base + 2] == b"II" else ">"
    u16 = lambda o: struct.unpack(order + "H", out[base + o:base + o + 2])[0]
    u32 = lambda o: struct.unpack(order + "I", out[base + o:base + o + 4])[0]

    def entry(ifd, tag):
        for k in range(u16(ifd)):
            if u16(ifd + 2 + 12 * k) == tag:
                return ifd + 2 + 12 * k
        return None

    def put(e, value):  # a SHORT or LONG value held in the entry itself
        if u16(e + 2) == 3:
            out[base + e + 8:base + e + 10] = struct.pack(order + "H", value)
        else:
            out[base + e + 8:base + e + 12] = struct.pack(order + "I", value)
    ifd0 = u32(4)
    orientation, exif_ifd = entry(ifd0, 0x112), entry(ifd0, 0x8769)
    if orientation is None or exif_ifd is None:
        return False
    sub = u32(exif_ifd + 8)
    xdim, ydim = entry(sub, 0xA002), entry(sub, 0xA003)
    if xdim is None or ydim is None:
        return False
    put(orientation, 6)
    put(xdim, stored.shape[1])
    put(ydim, stored.shape[0])
    with open(path, "wb") as f:
        f.write(out)
    return True


def traced_file(truth, path):
    json.dump({"width": truth["width"], "height": truth["height"], "y": truth["skyline_row"]}, open(path, "w"))


def errors(r, t):
    if r.get("status") != "registered":
        return None
    cr = r["center_ray"]
    return {"daz": angdiff(cr["azimuth_deg"], t["yaw_deg"]), "dp": cr["elevation_deg"] - t["pitch_deg"],
            "dr": r["roll_deg"] - t["roll_deg"], "dh": 100.0 * (r["hfov_deg"] / t["hfov_deg"] - 1.0)}


FALSE_DEG = 1.0  # a registration farther off than this (the centre ray's azimuth or pitch) is false


def pose_off_deg(e):
    """The larger of the centre ray's azimuth and pitch errors (errors()); infinity when not registered."""
    return max(abs(e["daz"]), abs(e["dp"])) if e else float("inf")


def is_false(e):
    """Whether a registration (errors(); None: not registered) is false."""
    return e is not None and pose_off_deg(e) > FALSE_DEG


def fmt(v, f):
    return format(v, f) if v is not None and not (isinstance(v, float) and math.isnan(v)) else "-"


def pose_table(title, rows, tol):
    print(f"\n== {title} ==")
    print(f"{'photo':<24}{'status':<11}{'d_az':>8}{'d_pitch':>8}{'d_roll':>8}{'d_hfov%':>8}{'inl':>6}{'ambig':>7}"
          f"{'k1':>7}{'k1true':>7}{'dem_px':>7}{'ms':>6}  note")
    for name, t, r in rows:
        e = errors(r, t)
        cam = r.get("camera") or {}
        k1 = cam.get("k") or [None]
        note = "" if r.get("status") == "registered" else r.get("message", "")[:60]
        if r.get("status") == "no_match" and r.get("candidates"):
            c0 = r["candidates"][0]
            if (r.get("camera") or {}).get("source") != "file":  # centred camera: the axis is the centre ray
                note = f"[best {angdiff(c0['azimuth_deg'], t['yaw_deg']):+.2f}/{c0['pitch_deg'] - t['pitch_deg']:+.2f}] " + note
        if is_false(e):
            note = "FALSE REGISTRATION " + note
        dem = r.get("dem") or {}
        print(f"{name:<24}{r.get('status', '?'):<11}{fmt(e and e['daz'], '8.3f'):>8}{fmt(e and e['dp'], '8.3f'):>8}"
              f"{fmt(e and e['dr'], '8.3f'):>8}{fmt(e and e['dh'], '8.2f'):>8}{fmt(r.get('inlier_fraction'), '6.2f'):>6}"
              f"{fmt(r.get('ambiguity_ratio'), '7.2f'):>7}{fmt(k1[0] if cam.get('k1_estimated') or cam.get('source') == 'file' else None, '7.3f'):>7}"
              f"{t['camera']['k'][0]:>7.3f}{fmt(dem.get('skyline_above_dem_px'), '7.2f'):>7}"
              f"{fmt((r.get('timing_ms') or {}).get('total'), '6.0f'):>6}  {note}")
    errs = [errors(r, t) for _, t, r in rows]
    good = [e for e in errs if pose_off_deg(e) <= tol]
    false = [n for (n, _, _), e in zip(rows, errs) if is_false(e)]
    reg = [e for e in errs if e]
    med = lambda k: statistics.median(abs(e[k]) for e in reg) if reg else float("nan")
    print(f"registered within {tol} deg (azimuth and pitch of the centre ray): {len(good)}/{len(rows)}; "
          f"registered: {len(reg)}; false (> 1 deg): {len(false)} {false}")
    print(f"median |d_az| {med('daz'):.3f} deg, |d_pitch| {med('dp'):.3f} deg, |d_roll| {med('dr'):.3f} deg, "
          f"|d_hfov| {med('dh'):.2f}%")
    times = [r["timing_ms"]["total"] for _, _, r in rows if r.get("timing_ms")]
    if times:
        print(f"in-process time: median {statistics.median(times):.0f} ms, max {max(times):.0f} ms")
    stderr = [n for n, _, r in rows if r.get("stderr", "").strip()]
    if stderr:
        print(f"stderr not empty: {stderr}")
    return len(good), len(false), med("daz"), med("dp")


def traced_columns(t):
    """The hand-traced columns of a truth file: (column, row) where traced."""
    return [(x, y) for x, y in enumerate(t["skyline_row"]) if y is not None]


def signed_errors(traced, s, top=0):
    """Skyline JSON `s` (read `top` rows below the photo's top) minus the
    trace, over the traced columns it gives a value in (positive: lower)."""
    return [s["y"][x] + top - y for x, y in traced if s["y"][x] is not None]


def extract_skyline(binary, image):
    """The skyline JSON `horizonreg skyline IMAGE --json` writes."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "s.json")
        subprocess.run([binary, "skyline", image, "--json", out], check=True, capture_output=True)
        return json.load(open(out))


def skyline_stability(binary, photos, qualities=(95, 50)):
    """Per photo and in all: the extracted skyline of each JPEG copy at
    `qualities` against the photo's own. Returns the share of the columns
    given in both that move by more than 1 px (over all copies); NaN without
    OpenCV."""
    cv2 = opencv_for("stability")
    if cv2 is None:
        return float("nan")

    def extract(image):
        return [math.nan if v is None else v for v in extract_skyline(binary, image)["y"]]

    print("\n== skyline stability: the photo's extracted skyline against its JPEG copies' ==")
    print(f"{'photo':<24}{'copy':>5}{'both':>6}{'>1px':>7}{'>3px':>7}{'lost':>6}{'new':>6}")
    tot = {q: [0, 0, 0] for q in qualities}  # both, > 1 px, > 3 px
    for name, t, photo_dir in photos:
        with tempfile.TemporaryDirectory() as tmp:
            source = os.path.join(photo_dir, t["image"])
            base = extract(source)
            colour = cv2.imread(source)
            for q in qualities:
                image = os.path.join(tmp, f"q{q}.jpg")
                cv2.imwrite(image, colour, [cv2.IMWRITE_JPEG_QUALITY, q])
                copy = extract(image)
                pairs = [(a, b) for a, b in zip(base, copy) if math.isfinite(a) and math.isfinite(b)]
                moved1 = sum(abs(a - b) > 1 for a, b in pairs)
                moved3 = sum(abs(a - b) > 3 for a, b in pairs)
                lost = sum(math.isfinite(a) and not math.isfinite(b) for a, b in zip(base, copy))
                new = sum(math.isfinite(b) and not math.isfinite(a) for a, b in zip(base, copy))
                for i, v in enumerate((len(pairs), moved1, moved3)):
                    tot[q][i] += v
                share = lambda k: 100.0 * k / len(pairs) if pairs else float("nan")
                print(f"{name:<24}{'q' + str(q):>5}{len(pairs):>6}{share(moved1):>6.1f}%{share(moved3):>6.1f}%"
                      f"{lost:>6}{new:>6}")
    for q in qualities:
        both, m1, m3 = tot[q]
        print(f"quality {q}: columns given in both {both}; moved more than 1 px: {100.0 * m1 / max(1, both):.1f}%, "
              f"more than 3 px: {100.0 * m3 / max(1, both):.1f}%")
    both = sum(v[0] for v in tot.values())
    moved = sum(v[1] for v in tot.values()) / both if both else float("nan")
    print(f"all copies: moved more than 1 px: {100.0 * moved:.1f}% of {both} columns")
    return moved


def skyline_table(binary, photos, thin_sky_px=None, shared=None, grey=False, jpeg_quality=None, framed=False):
    """Per photo and in all: the traced columns given a value and within 2 px.
    With thin_sky_px, each photo is first cropped from the top to leave that
    many rows above the traced horizon's highest point (the trace shifted
    with it); with framed as well, as many rows cut from the bottom. With
    shared (the registered mode), the skyline is the one
    `register --skyline-out` writes, the photo registered with no prior:
    read again near the DEM horizon where registered. With grey, the skyline
    of each photo's grey copy (luma, JPEG quality 95). With jpeg_quality, of
    each photo re-encoded as JPEG at that quality."""
    if grey or jpeg_quality:
        cv2 = opencv_for("gray-skyline" if grey else f"jpeg{jpeg_quality}-skyline")
        if cv2 is None:
            return float("nan"), float("nan")
        what = "grey copies" if grey else f"copies at JPEG quality {jpeg_quality}"
        print(f"\n== skyline of the {what} against the hand-traced horizon (traced columns only) ==")
    elif shared is not None:
        print("\n== register --skyline-out against the hand-traced horizon (traced columns only) ==")
    elif thin_sky_px is None:
        print("\n== skyline against the hand-traced horizon (traced columns only) ==")
    else:
        cv2 = opencv_for("thin-framed" if framed else "thin")
        if cv2 is None:
            return float("nan"), float("nan")
        print(f"\n== skyline with {thin_sky_px} px of sky left above the traced horizon (photos cropped"
              + (", as many rows cut from the bottom) ==" if framed else ") =="))
    # below / above: traced columns given a value more than 2 px under / over
    # the trace (under: a clearer inner edge taken; over: mostly a faint far
    # ridge the tracer left out, or cloud).
    print(f"{'photo':<24}{'traced':>7}{'given':>7}{'<=2px':>7}{'<=5px':>7}{'median':>8}{'p90':>7}{'below':>7}{'above':>7}")
    tot_traced = tot_given = tot_2 = tot_below = tot_above = 0
    for name, t, photo_dir in photos:
        traced = traced_columns(t)
        if not traced:
            print(f"{name:<24}{'(no trace)':>7}")
            continue
        with tempfile.TemporaryDirectory() as tmp:
            image, top = os.path.join(photo_dir, t["image"]), 0
            if thin_sky_px is not None:
                top = max(0, int(min(y for _, y in traced)) - thin_sky_px)
                full = cv2.imread(image)
                image = os.path.join(tmp, "crop.png")
                cv2.imwrite(image, full[top:full.shape[0] - top] if framed else full[top:])
            if grey:
                luma = cv2.imread(image, cv2.IMREAD_GRAYSCALE)
                image = os.path.join(tmp, "grey.jpg")
                cv2.imwrite(image, luma, [cv2.IMWRITE_JPEG_QUALITY, 95])
            if jpeg_quality:
                colour = cv2.imread(image)
                image = os.path.join(tmp, "compressed.jpg")
                cv2.imwrite(image, colour, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
            if shared is not None:
                r = register(binary, shared, photo_dir, name, t, ["--skyline-out", os.path.join(tmp, "s.json")])
                if r["status"] == "error":
                    print(f"{name:<24} error: {r['message']}")
                    continue
                s = json.load(open(os.path.join(tmp, "s.json")))
            else:
                s = extract_skyline(binary, image)
        signed = signed_errors(traced, s, top)
        d = [abs(v) for v in signed]
        below, above = sum(v > 2 for v in signed), sum(v < -2 for v in signed)
        tot_below += below
        tot_above += above
        given = len(d)
        w2 = sum(v <= 2 for v in d)
        w5 = sum(v <= 5 for v in d)
        tot_traced += len(traced)
        tot_given += given
        tot_2 += w2
        dd = sorted(d)
        print(f"{name:<24}{len(traced):>7}{100 * given / len(traced):>6.1f}%{100 * w2 / len(traced):>6.1f}%"
              f"{100 * w5 / len(traced):>6.1f}%{fmt(statistics.median(dd) if dd else None, '8.2f'):>8}"
              f"{fmt(dd[int(0.9 * len(dd))] if dd else None, '7.1f'):>7}"
              f"{100 * below / len(traced):>6.1f}%{100 * above / len(traced):>6.1f}%")
    w = tot_2 / tot_traced if tot_traced else float("nan")
    g = tot_given / tot_traced if tot_traced else float("nan")
    print(f"all traced columns: {tot_traced}; within 2 px: {100 * w:.1f}% (of the traced); given a value: {100 * g:.1f}%"
          + (f"; more than 2 px below: {100 * tot_below / tot_traced:.1f}%, above: {100 * tot_above / tot_traced:.1f}%"
             if tot_traced else ""))
    return w, g


# The photometric mode's changes: what other cameras, exposures and weather
# do to the same scene (applied in linear light where light is scaled).
def _linear(np, im):
    return (im.astype(np.float32) / 255.0) ** 2.2


def _encoded(np, x):
    return np.clip(255.0 * np.clip(x, 0.0, 1.0) ** (1 / 2.2) + 0.5, 0, 255).astype(np.uint8)


def _vignetted(np, im):
    h, w = im.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    r = np.hypot((x - w / 2) / (w / 2), (y - h / 2) / (w / 2))
    return _encoded(np, _linear(np, im) * (np.cos(np.arctan(0.9 * r)) ** 4)[..., None])


def _overcast(cv2, np, im):
    lab = cv2.cvtColor(im, cv2.COLOR_BGR2Lab).astype(np.float32)
    lab[..., 1:] = 128.0 + 0.3 * (lab[..., 1:] - 128.0)
    grey = cv2.cvtColor(np.clip(lab + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_Lab2BGR).astype(np.float32)
    return np.clip(0.75 * grey + 50.0, 0, 255).astype(np.uint8)


PHOTOMETRIC = [
    ("dark", "1.7 stops under", lambda cv2, np, im: _encoded(np, _linear(np, im) * 0.3)),
    ("bright", "1.3 stops over (clipped)", lambda cv2, np, im: _encoded(np, _linear(np, im) * 2.5)),
    ("noise", "sensor noise (sigma 6 of 255)", lambda cv2, np, im: np.clip(
        im.astype(np.float32) + np.random.default_rng(7).normal(0.0, 6.0, im.shape), 0, 255).astype(np.uint8)),
    ("blur", "soft focus (Gaussian sigma 1.5 px)", lambda cv2, np, im: cv2.GaussianBlur(im, (0, 0), 1.5)),
    ("vignette", "vignetting (cos^4, 0.9 rad at the corners' width)", lambda cv2, np, im: _vignetted(np, im)),
    ("warm", "warm white balance (R x1.3, B x0.7)", lambda cv2, np, im: _encoded(
        np, _linear(np, im) * np.array([0.7, 1.0, 1.3], np.float32))),
    ("cool", "cool white balance (B x1.3, R x0.75)", lambda cv2, np, im: _encoded(
        np, _linear(np, im) * np.array([1.3, 1.0, 0.75], np.float32))),
    ("veil", "a grey veil (flare, a dirty window: 60% scene, 40% grey 200)", lambda cv2, np, im: np.clip(
        0.6 * im.astype(np.float32) + 80.0, 0, 255).astype(np.uint8)),
    ("thick", "a thick veil (haze, flare: 50% scene, 50% grey 200)", lambda cv2, np, im: np.clip(
        0.5 * im.astype(np.float32) + 100.0, 0, 255).astype(np.uint8)),
    ("overcast", "a grey sky's light (chroma x0.3, then 25% grey 200)", _overcast),
]


def lens_bend(r):
    """A registration's fitted k1 and how far it moves the frame's side
    edges, in percent of the half-width (k1 (W / 2f)^2; positive:
    pincushion)."""
    cam = r.get("camera") or {}
    k, f, w = (cam.get("k") or [None])[0], cam.get("focal_px"), r.get("width")
    if k is None or not f or not w:
        return "k1 -"
    return f"k1 {k:+.3f} ({100 * k * (w / (2 * f)) ** 2:+.1f}%)"


def ring_of_wrong_positions(binary, shared, photos, images, truths, jobs, tmpdir, what, ceiling, check, mode,
                   extra_of=None, alt=True):
    """The ring's 468 wrong positions (RING_OFFSETS) on the photos or copies
    of them (images: name -> path, None for the photos as taken; truths:
    name -> the copy's truth, None for the photos'), with the options
    extra_of(i, name, truth) gives the i-th probe (none when None) and the
    altitude given or not (`alt`): prints each photo's registered and false
    ones; False when a check failed (more false ones than `ceiling`, or
    errors)."""
    probes = [(p, b, dist) + offset_position(p[1]["lat"], p[1]["lon"], b, dist)
              for p in photos for b, dist in RING_OFFSETS]
    truth_of = (lambda name, t: truths[name]) if truths else (lambda name, t: t)
    out = register_many(binary, shared, [
        dict(photo_dir=d, name=name, truth=truth_of(name, t), extra=extra_of(i, name, t) if extra_of else [],
             lat=lat, lon=lon, alt=alt, image=images[name] if images else None)
        for i, ((name, t, d), b, dist, lat, lon) in enumerate(probes)], jobs, tmpdir)
    print(f"\n== a ring of wrong positions: 12 bearings at 2, 3 and 5 km ({len(probes)} probes){what} ==")
    print(f"{'photo':<24}{'registered':>11}{'false':>6}  false ones (bearing/km: error deg, ambiguity, "
          "k1 and its bend at the frame's side edges)")
    n_reg = n_false = 0
    errs = []
    for name, t, _ in photos:
        reg, false = 0, []
        for ((pn, _, _), b, dist, _, _), r in zip(probes, out):
            if pn != name:
                continue
            if r.get("status") == "error":
                errs.append(f"{name} from {dist / 1000:.0f} km at {b}: {r.get('message')}")
            if r.get("status") != "registered":
                continue
            reg += 1
            err = pose_off_deg(errors(r, truth_of(name, t)))
            if err > FALSE_DEG:
                false.append(f"{b}/{dist // 1000}: {err:.1f}, {r.get('ambiguity_ratio')}, {lens_bend(r)}")
        n_reg, n_false = n_reg + reg, n_false + len(false)
        print(f"{name:<24}{reg:>11}{len(false):>6}  " + "; ".join(false))
    print(f"ring probes: {len(probes)}; registered: {n_reg} (none should); false (> 1 deg): {n_false}; "
          f"errors: {len(errs)}")
    for e in errs:
        print("  error: " + e)
    if check and (n_false > ceiling or errs):
        print(f"FAIL: --modes ring-{mode}: {n_false} false registrations (at most {ceiling:.0f}) or errors")
        return False
    return True


def photometric_modes(binary, shared, photos, modes, tmpdir, pool, jobs, floors, check):
    """The photometric and wrong-photometric modes (see the usage); False
    when a check failed."""
    cv2 = opencv_for("photometric")
    if cv2 is None:
        return not check
    import numpy as np
    ok = True
    copies = {}
    for key, _, change in PHOTOMETRIC:
        for name, t, d in photos:
            path = os.path.join(tmpdir, f"{name}.{key}.jpg")
            source = os.path.join(d, t["image"])
            if not write_jpeg_with_exif(cv2, change(cv2, np, cv2.imread(source)), source, path):
                print(f"FAIL: cannot write the {key} copy of {name}")
                return False
            copies[(name, key)] = path
    if "photometric" in modes:
        print("\n== no prior, each photo changed as another camera, exposure or weather would (JPEG 95, EXIF kept) ==")
        print(f"{'change':<10}{'within 0.5':>11}{'false':>6}{'sky<=2px':>9}{'given':>7}  not registered")
        all_traced = all_within = all_good = 0
        for key, what, _ in PHOTOMETRIC:
            def run(p):
                r = register(binary, shared, p[2], p[0], p[1], [], image=copies[(p[0], key)])
                return p, r, extract_skyline(binary, copies[(p[0], key)])
            good, false, traced, given, within, missed = 0, [], 0, 0, 0, []
            for (name, t, _), r, s in pool.map(run, photos):
                e = errors(r, t)
                if pose_off_deg(e) <= 0.5:
                    good += 1
                elif is_false(e):
                    false.append(name)
                else:
                    missed.append(name)
                columns = traced_columns(t)
                signed = signed_errors(columns, s)
                traced, given, within = traced + len(columns), given + len(signed), within + sum(
                    abs(v) <= 2 for v in signed)
            w = within / traced if traced else float("nan")
            all_traced, all_within, all_good = all_traced + traced, all_within + within, all_good + good
            print(f"{key:<10}{good:>8}/{len(photos):<2}{len(false):>6}{100 * w:>8.1f}%{100 * given / max(traced, 1):>6.1f}%"
                  f"  {' '.join(missed)}{' FALSE: ' + ' '.join(false) if false else ''}")
            if check and (good < floors.get("photometric-" + key, floors.get("photometric", 0)) or false):
                print(f"FAIL: photometric {key} ({what}) misses its floor or has a false registration")
                ok = False
        w = all_within / all_traced if all_traced else float("nan")
        print(f"all changes: {all_good} of {len(photos) * len(PHOTOMETRIC)} within 0.5 deg; skyline: {100 * w:.1f}% "
              f"of the traced columns within 2 px")
        if check and all_traced and w < floors.get("photometric-skyline", 0.0):
            print(f"FAIL: the changed copies' skyline {100 * w:.1f}% within 2 px is under its floor "
                  f"{100 * floors['photometric-skyline']:.1f}%")
            ok = False
    if "wrong-photometric" in modes:
        runs = [(pr, key) for pr in false_probe_list(photos, shared) for key, _, _ in PHOTOMETRIC]
        out = [(name, f"{label}, {key}", r) for (name, label, r), (_, key) in zip(probe_rows(
            binary, shared, [pr for pr, _ in runs], [probe_call(pr, image=copies[(pr[0][0], key)]) for pr, key in runs],
            jobs, tmpdir), runs)]
        if not report_wrong("wrong position (2-10 km away) or another region's DEM, every photometric change", out):
            ok = ok and not check
    for key, what, _ in PHOTOMETRIC:
        if "ring-" + key in modes and not ring_of_wrong_positions(
                binary, shared, photos, {name: copies[(name, key)] for name, _, _ in photos},
                None, jobs, tmpdir, ", " + what, floors.get("ring-" + key, 0), check, key):
            ok = False
    return ok


def main():
    argv = sys.argv[1:]
    opt = lambda k, d=None: argv[argv.index(k) + 1] if k in argv else d
    check = "--check" in argv
    modes = opt("--modes", ",".join(ALL_MODES)).split(",")
    only = set(opt("--only").split(",")) if opt("--only") else None
    overlay_dir = opt("--overlay-dir")
    jobs = int(opt("--jobs", "2"))
    floors = {"plain": 12, "camera": 12, "initial": 13, "skyline": 0.9, "thin": 0.9, "skyline-given": 0.95,
              "registered-skyline": 0.9, "registered-skyline-given": 0.95,
              "thin-given": 0.95, "ring": 0, "ring-camera": 0, "ring-initial": 0, "ring-sensors": 0, "ring-noexif": 0, "ring-hfov": 0, "ring-range": 0, "ring-noalt": 0, "ring-noalt-hfov": 0, "hfov": 12,
              "sensors": 0, "noexif": 0, "reencode": 0, "gray": 0, "upscale2": 0, "upscale4": 0, "downscale2": 0, "jpeg50": 0, "jpeg30": 0, "crop": 0, "crop-narrow": 0, "ring-crop": 0, "ring-crop-narrow": 0, "tilted": 0, "ring-tilted": 0, "stations": 0, "turned": 0, "banner": 0, "cloud": 0, "cloud-small": 0, "sky-cloud": 0, "occluder": 0, "cables": 0, "contrails": 0, "sun": 0, "roof": 0, "gray-skyline": 0.0, "stability": 1.0,
              "jpeg30-skyline": 0.0, "photometric": 0, "photometric-skyline": 0.0, "thin-framed": 0.0,
              "thin-framed-given": 0.0}
    for kv in (opt("--floors") or "").split(","):
        if "=" in kv:
            k, v = kv.split("=")
            floors[k] = float(v)
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and
            (i == 0 or argv[i - 1] not in ("--modes", "--only", "--overlay-dir", "--jobs", "--floors"))]
    if len(args) != 2 or "--help" in argv or "-h" in argv:
        print(__doc__)
        return 0 if ("--help" in argv or "-h" in argv) else 2
    binary, shared = args[0], args[1]
    real = os.path.join(shared, "real")
    if not os.path.isdir(real):
        print("SKIPPED: ../shared/real is absent")
        return 77
    photos = []
    for sub in sorted(os.listdir(real)):
        d = os.path.join(real, sub)
        if not os.path.isdir(d):
            continue
        for f in sorted(os.listdir(d)):
            if f.endswith(".truth.json") and (not only or f[:-11] in only):
                photos.append((f[:-11], json.load(open(os.path.join(d, f))), d))
    if overlay_dir:
        os.makedirs(overlay_dir, exist_ok=True)
    failed = False
    tmpdir = tempfile.mkdtemp(prefix="eval_real_")
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=jobs)

    def run_all(fn):
        return list(pool.map(fn, photos))

    if "plain" in modes:
        rows = run_all(lambda p: (p[0], p[1], register(
            binary, shared, p[2], p[0], p[1], [],
            overlay=os.path.join(overlay_dir, p[0] + ".png") if overlay_dir else None)))
        good, false, maz, mp = pose_table("no prior", rows, 0.5)
        if check and (good < floors["plain"] or false):
            print("FAIL: no-prior registration misses its floor or has a false registration")
            failed = True
    if "hfov" in modes:
        rows = run_all(lambda p: (p[0], p[1], register(binary, shared, p[2], p[0], p[1],
                                                       variant_args("hfov", p[0], p[1], 0, {}))))
        good, false, _, _ = pose_table("--hfov from the truth (a known opening angle, +-3% searched)", rows, 0.5)
        if check and (good < floors["hfov"] or false):
            print("FAIL: --hfov registration misses its floor or has a false registration")
            failed = True
    if "camera" in modes:
        files = variant_files("camera", photos, tmpdir)

        def with_camera(p):
            return p[0], p[1], register(binary, shared, p[2], p[0], p[1], variant_args("camera", p[0], p[1], 0, files))
        good, false, _, _ = pose_table("--camera from the truth's camera model", run_all(with_camera), 0.3)
        if check and (good < floors["camera"] or false):
            print("FAIL: --camera registration misses its floor or has a false registration")
            failed = True
    for mode in [m for m in ("initial", "sensors") if m in modes]:
        jobs_list = [(p, i) for p in photos for i in range(len(INITIAL_OFFSETS))]
        files = variant_files(mode, photos, tmpdir)

        def initial(po):
            (name, t, d), i = po
            daz, dp = INITIAL_OFFSETS[i]
            return (f"{name} {daz:+d}/{dp:+d}", t,
                    register(binary, shared, d, name, t, variant_args(mode, name, t, i, files)))
        rows = list(pool.map(initial, jobs_list))
        title = ("--initial 2 deg off (azimuth or pitch), no camera file" if mode == "initial" else
                 "--sensors: a compass and inclinometer 2 deg off (azimuth or pitch)")
        good, false, _, _ = pose_table(title, rows, 0.5)
        converged_photos = len({n.split()[0] for n, t, r in rows
                                if all(pose_off_deg(errors(rr, tt)) <= 0.5
                                       for nn, tt, rr in rows if nn.split()[0] == n.split()[0])})
        print(f"photos converging from all four starts: {converged_photos}/{len(photos)}")
        if check and (converged_photos < floors[mode] or false):
            print(f"FAIL: --{mode} misses its floor or has a false registration")
            failed = True
    # Plain registration of a copy of each photo: its pixels alone (no EXIF),
    # re-encoded with its EXIF kept, or turned to grey with its EXIF kept.
    def without_exif(cv2, source, path):
        return cv2.imwrite(path, cv2.imread(source))

    def jpeg_copy(cv2, source, path, grey=False, quality=95):
        image = cv2.imread(source, cv2.IMREAD_GRAYSCALE if grey else cv2.IMREAD_COLOR)
        return write_jpeg_with_exif(cv2, image, source, path, quality)

    def grey(cv2, source, path):
        return jpeg_copy(cv2, source, path, grey=True)

    def compressed(quality):
        return lambda cv2, source, path: jpeg_copy(cv2, source, path, quality=quality)

    def bannered(cv2, source, path):
        # A webcam's timestamp strip: black, 28 rows per 1000 columns, white
        # text, over the top of the photo (JPEG quality 95, EXIF kept).
        image = cv2.imread(source)
        s = image.shape[1] / 1000.0
        cv2.rectangle(image, (0, 0), (image.shape[1], int(28 * s)), (0, 0, 0), -1)
        cv2.putText(image, "2009-08-03 19:54:10  CAM 2  T=12.4C", (int(8 * s), int(20 * s)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.6 * s, (255, 255, 255), max(1, int(2 * s)))
        return write_jpeg_with_exif(cv2, image, source, path)

    def skyline_rows(source):
        # Where the clouds go: the photo's hand-traced skyline, or, untraced,
        # the one `skyline` extracts.
        rows = json.load(open(source[:source.rfind(".")] + ".truth.json")).get("skyline_row") or []
        return rows if any(v is not None for v in rows) else extract_skyline(binary, source)["y"]

    def painted(draw):
        # The photo with draw(cv2, image, skyline rows) painted over it, JPEG quality 95, EXIF kept.
        return lambda cv2, source, path: write_jpeg_with_exif(
            cv2, draw(cv2, cv2.imread(source), skyline_rows(source)), source, path)

    def clouded(share):
        # A cap cloud over the highest stretch of the skyline.
        return painted(lambda cv2, image, rows: cap_cloud(cv2, image, rows, share))

    def sky_clouded(cv2, source, path):
        # A cumulus floating in the photo's widest sky; a photo with too
        # little sky for one is written unchanged.
        image = cv2.imread(source)
        clouded_image = sky_cloud(cv2, image, skyline_rows(source))
        return write_jpeg_with_exif(cv2, image if clouded_image is None else clouded_image, source, path)

    def resized(factor):
        # Bicubic up (a DSLR's or a phone's pixel count); area averaging down
        # (a web page's or a webcam's 360-540 columns at half the size).
        def write(cv2, source, path):
            image = cv2.imread(source)
            interpolation = cv2.INTER_CUBIC if factor > 1 else cv2.INTER_AREA
            out = cv2.resize(image, None, fx=factor, fy=factor, interpolation=interpolation)
            return write_jpeg_with_exif(cv2, out, source, path)
        return write

    for mode, suffix, title, write in (
            ("noexif", ".noexif.png", "no prior, no EXIF (the pixels alone, as PNG)", without_exif),
            ("reencode", ".q95.jpg", "no prior, re-encoded as JPEG quality 95 (EXIF kept)", compressed(95)),
            ("gray", ".gray.jpg", "no prior, grey (luma only, JPEG quality 95, EXIF kept)", grey),
            ("upscale2", ".x2.jpg", "no prior, upscaled 2x (bicubic, JPEG quality 95, EXIF kept)", resized(2)),
            ("upscale4", ".x4.jpg", "no prior, upscaled 4x (bicubic, JPEG quality 95, EXIF kept)", resized(4)),
            ("downscale2", ".half.jpg", "no prior, half the size (area averaging, JPEG quality 95, EXIF kept)",
             resized(0.5)),
            ("jpeg50", ".q50.jpg", "no prior, re-encoded as JPEG quality 50 (EXIF kept)", compressed(50)),
            ("jpeg30", ".q30.jpg", "no prior, re-encoded as JPEG quality 30 (EXIF kept)", compressed(30)),
            ("banner", ".banner.jpg", "no prior, a webcam's timestamp strip over the top (JPEG quality 95, EXIF "
             "kept)", bannered),
            ("cloud", ".cloud.jpg", "no prior, a cap cloud over the highest fifth of the skyline (JPEG "
             "quality 95, EXIF kept)", clouded(0.2)),
            ("sky-cloud", ".skycloud.jpg", "no prior, a cumulus floating in the sky, clear of the skyline (JPEG "
             "quality 95, EXIF kept)", sky_clouded),
            ("cloud-small", ".cloud10.jpg", "no prior, a cap cloud over the highest tenth of the skyline (JPEG "
             "quality 95, EXIF kept)", clouded(0.1)),
            ("occluder", ".occluder.jpg", "no prior, a conifer and a power pole standing into the sky (JPEG "
             "quality 95, EXIF kept)", painted(occluders)),
            ("cables", ".cables.jpg", "no prior, two power cables sagging across the sky (JPEG quality 95, "
             "EXIF kept)", painted(cables)),
            ("contrails", ".contrails.jpg", "no prior, two aircraft contrails across the sky (JPEG quality 95, "
             "EXIF kept)", painted(contrails)),
            ("sun", ".sun.jpg", "no prior, the sun low over a ridge with its glow and flare (JPEG quality 95, "
             "EXIF kept)", painted(sun_glare)),
            ("roof", ".roof.jpg", "no prior, a hut's roof in the foreground hiding a third of the skyline "
             "(JPEG quality 95, EXIF kept)", painted(roof)),
            ("turned", ".turned.jpg", "no prior, stored a quarter turn with EXIF Orientation 6 (a camera held "
             "upright)", turned_copy)):
        ring = "ring-" + mode in modes and mode != "noexif"  # ring-noexif: the ring with --no-exif (above)
        if mode not in modes and not ring:
            continue
        cv2 = opencv_for(mode)
        if cv2 is None:
            failed = failed or check
            continue
        if ring:
            images = {}
            for name, t, d in photos:
                images[name] = os.path.join(tmpdir, name + suffix)
                if not write(cv2, os.path.join(d, t["image"]), images[name]):
                    print(f"FAIL: cannot write the {mode} copy of {name}")
                    failed = True
            if len(images) == len(photos) and not ring_of_wrong_positions(
                    binary, shared, photos, images, None, jobs, tmpdir,
                    ", " + title.replace("no prior, ", ""), floors.get("ring-" + mode, 0), check, mode):
                failed = True
        if mode not in modes:
            continue

        def copy_of(p):
            path = os.path.join(tmpdir, p[0] + suffix)
            if not write(cv2, os.path.join(p[2], p[1]["image"]), path):
                return p[0], p[1], {"status": "error", "message": f"cannot write the {mode} copy (OpenCV)"}
            return p[0], p[1], register(binary, shared, p[2], p[0], p[1], [], image=path)
        good, false, _, _ = pose_table(title, run_all(copy_of), 0.5)
        if check and (good < floors[mode] or false):
            print(f"FAIL: --modes {mode} misses its floor or has a false registration")
            failed = True
    # Cropped copies (the crop's own truth) and the wrong probes on them:
    # 3/4 of the width, the left part of every other photo and the right of
    # the rest; the centre half (a portrait frame from a landscape photo).
    for mode, share, what in (("crop", 0.75, "cropped to 3/4 of the width"),
                              ("crop-narrow", 0.5, "cropped to the centre half of the width (portrait)")):
        if mode not in modes and "wrong-" + mode not in modes and "ring-" + mode not in modes:
            continue
        cv2 = opencv_for(mode)
        crops = {}
        for i, (name, t, d) in enumerate(photos if cv2 else []):
            path = os.path.join(tmpdir, f"{name}.{mode}.jpg")
            where = "centre" if share == 0.5 else ("right" if i % 2 else "left")
            crops[name] = (path, cropped_copy(cv2, t, os.path.join(d, t["image"]), path, where, share))
        if cv2 is None or not all(ct for _, ct in crops.values()):
            print(f"FAIL: cannot write the copies of --modes {mode}")
            failed = True
            continue
        if mode in modes:
            def crop_of(p):
                path, ct = crops[p[0]]
                return p[0], ct, register(binary, shared, p[2], p[0], ct, [], image=path)
            good, false, _, _ = pose_table(f"no prior, {what} (EXIF kept)", run_all(crop_of), 0.5)
            if check and (good < floors[mode] or false):
                print(f"FAIL: --modes {mode} misses its floor or has a false registration")
                failed = True
        if "wrong-" + mode in modes:
            probes = false_probe_list(photos, shared)
            out = probe_rows(binary, shared, probes, [probe_call(pr, image=crops[pr[0][0]][0], truth=crops[pr[0][0]][1])
                                                      for pr in probes], jobs, tmpdir)
            if not report_wrong(f"wrong position (2-10 km away) or another region's DEM, {what}", out) and check:
                failed = True
        if "ring-" + mode in modes and not ring_of_wrong_positions(
                binary, shared, photos, {name: c[0] for name, c in crops.items()},
                {name: c[1] for name, c in crops.items()}, jobs, tmpdir, ", " + what, floors["ring-" + mode], check, mode):
            failed = True
    # Tilted copies (a camera held askew), their truth, the wrong probes on them.
    if {"tilted", "wrong-tilted", "ring-tilted"} & set(modes):
        cv2 = opencv_for("tilted")
        tilted = {}
        for i, (name, t, d) in enumerate(photos if cv2 else []):
            for angle in (TILT_DEG, -TILT_DEG):
                path = os.path.join(tmpdir, f"{name}.tilt{angle:+.0f}.png")
                tilted[(name, angle)] = (path, tilted_copy(cv2, t, os.path.join(d, t["image"]), path, angle))
        if cv2 is None or not all(ct for _, ct in tilted.values()):
            print("FAIL: cannot write the tilted copies")
            failed = True
        else:
            def hfov_of(ct):
                return ["--hfov", f"{ct['hfov_deg']:.3f}"]
            if "tilted" in modes:
                photo_dir = {name: d for name, _, d in photos}

                def tilted_of(key):
                    path, ct = tilted[key]
                    return f"{key[0][:20]} {key[1]:+.0f}", ct, register(binary, shared, photo_dir[key[0]], key[0], ct,
                                                                         hfov_of(ct), image=path)
                good, false, _, _ = pose_table(
                    f"no prior, turned by +-{TILT_DEG:.0f} deg and cut (PNG, --hfov of the cut frame)",
                    list(pool.map(tilted_of, list(tilted))), 0.5)
                if check and (good < floors["tilted"] or false):
                    print("FAIL: --modes tilted misses its floor or has a false registration")
                    failed = True
            # One copy per photo for the probes: +6 deg for every other photo, -6 for the rest.
            one = {name: tilted[(name, TILT_DEG if i % 2 == 0 else -TILT_DEG)] for i, (name, _, _) in enumerate(photos)}
            if "wrong-tilted" in modes:
                probes = false_probe_list(photos, shared)
                out = probe_rows(binary, shared, probes, [
                    probe_call(pr, extra=hfov_of(one[pr[0][0]][1]), image=one[pr[0][0]][0], truth=one[pr[0][0]][1])
                    for pr in probes], jobs, tmpdir)
                if not report_wrong("wrong position (2-10 km away) or another region's DEM, turned and cut", out) \
                        and check:
                    failed = True
            if "ring-tilted" in modes and not ring_of_wrong_positions(
                    binary, shared, photos, {name: c[0] for name, c in one.items()},
                    {name: c[1] for name, c in one.items()}, jobs, tmpdir, ", turned and cut",
                    floors["ring-tilted"], check, "tilted", extra_of=lambda i, name, t: hfov_of(one[name][1])):
                failed = True
    # The hand-traced horizon (the matching alone), with k1 fitted and
    # without; a false registration fails the check with k1 only.
    for mode, extra, title in (("traced", [], "--skyline: the hand-traced horizon (matching alone)"),
                               ("traced-pinhole", ["--pinhole"], "--skyline --pinhole: the hand-traced horizon, no k1")):
        if mode not in modes:
            continue
        def traced(p, extra=extra):
            if not any(y is not None for y in p[1]["skyline_row"]):
                return None
            path = os.path.join(tmpdir, p[0] + ".traced.json")
            traced_file(p[1], path)
            return p[0], p[1], register(binary, shared, p[2], p[0], p[1], ["--skyline", path] + extra)
        rows = [r for r in run_all(traced) if r]
        _, false, _, _ = pose_table(title, rows, 0.5)
        if check and false and mode == "traced":
            failed = True
    if "registered-skyline" in modes:
        w, g = skyline_table(binary, photos, shared=shared)
        if check and (w < floors["registered-skyline"] or g < floors["registered-skyline-given"]):
            print("FAIL: the registered skyline's accuracy or coverage misses its floor")
            failed = True
    if "gray-skyline" in modes:
        w, _ = skyline_table(binary, photos, grey=True)
        if check and not w >= floors["gray-skyline"]:
            print("FAIL: the grey copies' skyline accuracy misses its floor")
            failed = True
    if "jpeg30-skyline" in modes:
        w, _ = skyline_table(binary, photos, jpeg_quality=30)
        if check and not w >= floors["jpeg30-skyline"]:
            print("FAIL: the quality-30 copies' skyline accuracy misses its floor")
            failed = True
    if "stability" in modes:
        moved = skyline_stability(binary, photos)
        if check and not moved <= floors["stability"]:  # NaN (no OpenCV) fails too
            print("FAIL: the skyline moves with JPEG re-encoding more than its ceiling allows")
            failed = True
    if "skyline" in modes:
        w, g = skyline_table(binary, photos)
        if check and (w < floors["skyline"] or g < floors["skyline-given"]):
            print("FAIL: skyline accuracy or coverage misses its floor")
            failed = True
    for mode, framed, what in (("thin", False, ""), ("thin-framed", True, ", no foreground,")):
        if mode in modes:
            w, g = skyline_table(binary, photos, THIN_SKY_PX, framed=framed)
            if check and not (w >= floors[mode] and g >= floors[mode + "-given"]):  # NaN (no OpenCV) fails too
                print(f"FAIL: skyline accuracy or coverage under a thin strip of sky{what} misses its floor")
                failed = True
    if "batch-equals" in modes:
        probes = false_probe_list(photos, shared)
        calls = [probe_call(pr) for pr in probes]
        one = list(pool.map(lambda c: register(binary, shared, **c), calls))
        many = register_many(binary, shared, calls, jobs, tmpdir)
        keys = ("status", "message", "azimuth_deg", "pitch_deg", "roll_deg", "hfov_deg", "ambiguity_ratio",
                "inlier_fraction", "evidence")
        differ = [(pr[0][0], pr[1], k, a.get(k), b.get(k)) for pr, a, b in zip(probes, one, many) for k in keys
                  if a.get(k) != b.get(k)]
        print(f"\n== the wrong probes by `register` and by `batch --check-every-photo`: {len(probes)} probes, "
              f"{sum(a.get('status') == 'registered' for a in one)} registered, {len(differ)} fields differ ==")
        for name, label, k, a, b in differ[:20]:
            print(f"  {name} from {label}: {k} register {a!r} batch {b!r}")
        if check and differ:
            print("FAIL: batch rows differ from register's")
            failed = True
    for mode in ("wrong", "wrong-camera", "wrong-initial", "wrong-noexif", "wrong-hfov", "wrong-range"):
        if mode not in modes:
            continue
        variant = mode.partition("-")[2]
        files = variant_files(variant, photos, tmpdir)

        probes = false_probe_list(photos, shared)
        out = probe_rows(binary, shared, probes, [probe_call(pr, variant_args(variant, pr[0][0], pr[0][1], i, files))
                                                  for i, pr in enumerate(probes)], jobs, tmpdir)
        if not report_wrong(f"wrong position (2-10 km away) or another region's DEM{VARIANT_TITLES[variant]}", out) \
                and check:
            failed = True
    # The wrong probes on altered copies: a wide photo read at its reduced
    # size, a strongly compressed one, must refuse a wrong position as the
    # photo does.
    for mode, suffix, what, write in (("wrong-upscale4", ".wrong.x4.jpg", "the photos upscaled 4x", resized(4)),
                                      ("wrong-downscale2", ".wrong.half.jpg", "the photos at half the size",
                                       resized(0.5)),
                                      ("wrong-banner", ".wrong.banner.jpg", "the photos under a timestamp strip",
                                       bannered),
                                      ("wrong-jpeg30", ".wrong.q30.jpg", "the photos as JPEG quality 30",
                                       compressed(30)),
                                      ("wrong-occluder", ".wrong.occluder.jpg", "a conifer and a power pole in "
                                       "the sky", painted(occluders)),
                                      ("wrong-cables", ".wrong.cables.jpg", "two power cables across the sky",
                                       painted(cables)),
                                      ("wrong-contrails", ".wrong.contrails.jpg", "two contrails across the sky",
                                       painted(contrails)),
                                      ("wrong-sun", ".wrong.sun.jpg", "the sun low over a ridge",
                                       painted(sun_glare)),
                                      ("wrong-roof", ".wrong.roof.jpg", "a hut's roof in the foreground",
                                       painted(roof))):
        if mode not in modes:
            continue
        cv2 = opencv_for(mode)
        if cv2 is None:
            failed = failed or check
            continue
        copies = {}
        for name, t, d in photos:
            copies[name] = os.path.join(tmpdir, name + suffix)
            write(cv2, os.path.join(d, t["image"]), copies[name])

        probes = false_probe_list(photos, shared)
        out = probe_rows(binary, shared, probes, [probe_call(pr, image=copies[pr[0][0]]) for pr in probes], jobs,
                         tmpdir)
        if not report_wrong(f"wrong position (2-10 km away) or another region's DEM, {what}", out) and check:
            failed = True
    for ring_mode in [m for m in ("ring", "ring-camera", "ring-initial", "ring-sensors", "ring-noexif", "ring-hfov", "ring-range", "ring-noalt",
                                  "ring-noalt-hfov")
                      if m in modes]:
        variant = ring_mode.partition("-")[2]
        files = variant_files(variant, photos, tmpdir)
        if not ring_of_wrong_positions(binary, shared, photos, None, None, jobs, tmpdir, VARIANT_TITLES[variant],
                              floors[ring_mode], check, variant or "plain",
                              extra_of=lambda i, name, t, v=variant, f=files: variant_args(v, name, t, i, f),
                              alt=not variant.startswith("noalt")):
            failed = True
    if "perturbed" in modes:
        runs = [(p, "truth", None, None, None, True, pe) for p in photos for pe in PERTURBATIONS]
        runs += [w + (w[2] is None, pe) for w in false_probe_list(photos, shared) for pe in PERTURBATIONS]

        results = register_many(binary, shared, [
            dict(photo_dir=d, name=name, truth=t, extra=pe, dem=dem, lat=lat, lon=lon, alt=alt)
            for (name, t, d), label, dem, lat, lon, alt, pe in runs], jobs, tmpdir)
        print(f"\n== perturbed: plain and wrong under {len(PERTURBATIONS)} samplings and refractions "
              "(" + "; ".join(" ".join(pe) or "defaults" for pe in PERTURBATIONS) + ") ==")
        print(f"{'photo':<24}{'correct':>8}  cost ratios")
        correct, total, false_runs, wrong_ratios = 0, 0, [], []
        errs = [(p[0], label, " ".join(pe), r.get("message")) for (p, label, _, _, _, _, pe), r in zip(runs, results)
                if r.get("status") == "error"]
        for name, _, _ in photos:
            ratios, ok = [], 0
            for (p, label, _, _, _, _, pe), r in zip(runs, results):
                if p[0] != name:
                    continue
                e = errors(r, p[1])
                if label == "truth":
                    total += 1
                    ratios.append(r.get("ambiguity_ratio"))
                    if pose_off_deg(e) <= 0.5:
                        ok += 1
                    elif is_false(e):
                        false_runs.append((name, "its own position", " ".join(pe)))
                else:
                    if r.get("status") == "registered":
                        false_runs.append((name, label, " ".join(pe)))
                    a = r.get("ambiguity_ratio")
                    if a is not None and a < 1000:
                        wrong_ratios.append((a, name, label, " ".join(pe)))
            correct += ok
            print(f"{name:<24}{ok:>6}/{len(PERTURBATIONS)}  " + " ".join(fmt(a, '.2f') for a in ratios))
        wrong_ratios.sort(reverse=True)
        near = [w for w in wrong_ratios if w[0] >= GATE_RATIO - 0.05]
        print(f"registered within 0.5 deg: {correct}/{total} runs; false registrations: {len(false_runs)} of "
              f"{len(runs)} runs")
        for n, l, pe in false_runs:
            print(f"  FALSE REGISTRATION: {n} from {l} ({pe or 'defaults'})")
        print(f"wrong probes: highest cost ratio {wrong_ratios[0][0] if wrong_ratios else '-'}; within 0.05 of the "
              f"gate ({GATE_RATIO}): {len(near)}")
        for a, n, l, pe in near:
            print(f"  near miss: {n} from {l} ({pe or 'defaults'}): {a}")
        for n, l, pe, m in errs:
            print(f"  error: {n} from {l} ({pe or 'defaults'}): {m}")
        if check and (false_runs or errs):
            print("FAIL: a perturbed run registered falsely or failed")
            failed = True
    if any(m in modes for m in ("photometric", "wrong-photometric")) or any(
            "ring-" + key in modes for key, _, _ in PHOTOMETRIC):
        if not photometric_modes(binary, shared, photos, modes, tmpdir, pool, jobs, floors, check):
            failed = True
    if any(m in modes for m in ("stations", "wrong-stations", "ring-stations")):
        if not stations_modes(binary, shared, photos, modes, tmpdir, pool, floors, check):
            failed = True
    return 1 if failed else 0


def stations_modes(binary, shared, photos, modes, tmpdir, pool, floors, check):
    """The stations, wrong-stations and ring-stations modes (see the usage);
    False when a check failed."""
    cv2 = opencv_for("stations")
    if cv2 is None:
        return False
    # Each photo, its copy at JPEG quality 95 (EXIF kept) and its pixels
    # alone (PNG, no EXIF: a webcam's), grouped by station (its position),
    # in the order of the photos.
    stations = collections.OrderedDict()
    for name, t, d in photos:
        copy = os.path.join(tmpdir, name + ".station-q95.jpg")
        bare = os.path.join(tmpdir, name + ".station-noexif.png")
        pixels = cv2.imread(os.path.join(d, t["image"]))
        if not write_jpeg_with_exif(cv2, pixels, os.path.join(d, t["image"]), copy) or not cv2.imwrite(bare, pixels):
            print(f"FAIL: cannot write the copies of --modes stations")
            return False
        key = (t["lat"], t["lon"], t["alt_m"], t["dem"])
        stations.setdefault(key, []).extend([(name, t, os.path.abspath(os.path.join(d, t["image"]))),
                                             (name + " (q95)", t, os.path.abspath(copy)),
                                             (name + " (no EXIF)", t, os.path.abspath(bare))])

    def run_batch(members, lat, lon, dem, alt, extra, tag):
        """The rows of one batch (image path -> row)."""
        k = hashlib.sha1(repr((members[0][2], lat, lon, dem, alt, extra)).encode()).hexdigest()[:12]
        height = {"alt_m": alt} if alt is not None else {"agl_m": 2}
        got, p = batch_rows(binary, shared, dem, [dict(height, image=image, lat=lat, lon=lon)
                                                  for _, _, image in members], extra,
                            os.path.join(tmpdir, f"st_{tag}_{k}"))
        if p.returncode != 0:
            return {image: {"status": "error", "message": p.stderr.strip()[:120]} for _, _, image in members}
        return got

    ok = True
    vouched = lambda r: "station_vouched_by" in (r.get("position_check") or {})
    if "stations" in modes:
        print("\n== batch by station (each photo, its JPEG quality 95 copy and its EXIF-less copy), with and "
              "without --check-every-photo ==")
        print(f"{'photo':<30}{'every':>11}{'d_az':>8}{'d_pitch':>8}{'ms':>7}{'vouched':>11}{'d_az':>8}{'d_pitch':>8}"
              f"{'ms':>7}  note")
        jobs = [(members, every) for members in stations.values() for every in (True, False)]
        results = list(pool.map(lambda j: run_batch(j[0], j[0][0][1]["lat"], j[0][0][1]["lon"], j[0][0][1]["dem"],
                                                    j[0][0][1]["alt_m"], ["--check-every-photo"] if j[1] else [],
                                                    "every" if j[1] else "vouched"), jobs))
        good = false = differ = light = gained = 0
        ms = {True: [], False: []}
        for (members, _), every_rows, vouched_rows in zip(jobs[::2], results[::2], results[1::2]):
            for name, t, image in members:
                a, b = every_rows.get(image, {}), vouched_rows.get(image, {})
                ea, eb = errors(a, t), errors(b, t)
                for r, e in ((a, ea), (b, eb)):
                    if is_false(e):
                        false += 1
                good += pose_off_deg(eb) <= 0.5
                same = a.get("status") == b.get("status") and (not ea or (abs(ea["daz"] - eb["daz"]) < 1e-9 and
                                                                           abs(ea["dp"] - eb["dp"]) < 1e-9))
                # registered only within the station camera's opening angle
                by_station = (not ea and eb and a.get("status") == "no_match" and
                              (b.get("hfov_search_deg") or [None] * 3)[2] == "station")
                gained += bool(by_station)
                same = same or by_station
                differ += not same
                light += vouched(b)
                for every, r in ((True, a), (False, b)):
                    if r.get("timing_ms"):
                        ms[every].append(r["timing_ms"]["total"])
                cell = lambda r, e: (f"{r.get('status', '-'):>11}{fmt(e and e['daz'], '8.3f'):>8}"
                                     f"{fmt(e and e['dp'], '8.3f'):>8}{fmt((r.get('timing_ms') or {}).get('total'), '7.0f'):>7}")
                print(f"{name:<30}{cell(a, ea)}{cell(b, eb)}  {'vouched' if vouched(b) else ''}"
                      f"{' (station opening angle)' if by_station else ''}{'' if same else ' DIFFERS'}")
        print(f"registered within 0.5 deg (vouched run): {good}/{sum(len(m) for m in stations.values())}; "
              f"rows vouched: {light}; registered only within the station camera's opening angle: {gained}; "
              f"other decisions or poses that differ: {differ}; false (> 1 deg): {false}")
        med = lambda v: statistics.median(v) if v else float("nan")
        print(f"in-process time per photo: median {med(ms[True]):.0f} ms, total {sum(ms[True]) / 1000:.1f} s with "
              f"--check-every-photo; median {med(ms[False]):.0f} ms, total {sum(ms[False]) / 1000:.1f} s vouched")
        if check and (differ or false or good < floors["stations"]):
            print("FAIL: --modes stations: a decision differs, a registration is false or below the floor")
            ok = False
    for mode, offsets in (("wrong-stations", WRONG_OFFSETS), ("ring-stations", RING_OFFSETS)):
        if mode not in modes:
            continue
        probes = []
        for members in stations.values():
            t = members[0][1]
            for bearing, dist in offsets:
                lat, lon = offset_position(t["lat"], t["lon"], bearing, dist)
                probes.append((members, f"{dist / 1000:.0f} km at {bearing}", t["dem"], lat, lon, t["alt_m"]))
            if mode == "wrong-stations":
                for dem, lat, lon in OTHER_DEMS:
                    if os.path.exists(os.path.join(shared, "dem", dem)):
                        probes.append((members, dem, dem, lat, lon, None))
        outs = list(pool.map(lambda pr: run_batch(pr[0], pr[3], pr[4], pr[2], pr[5], [], mode), probes))
        # As the ring's probes: a registration more than 1 deg off the truth
        # (in azimuth or pitch of the centre ray) is false; one within 1 deg
        # from 2 km away is the skyline fitting from there, reported.
        bad, near, errs, light, rows = [], [], [], 0, 0
        for (members, label, *_), out in zip(probes, outs):
            for name, t, image in members:
                r = out.get(image, {"status": "error", "message": "missing from the batch output"})
                rows += 1
                light += vouched(r)
                e = errors(r, t)
                if is_false(e):
                    bad.append((name, label, e, vouched(r)))
                elif e:
                    near.append((name, label, e, vouched(r)))
                elif r.get("status") == "error":
                    errs.append((name, label, r.get("message")))
        print(f"\n== {mode}: every station's batch (photos and copies) from a wrong position or another region's "
              f"DEM: none may register more than 1 deg off ==")
        for what, lst in (("FALSE REGISTRATION", bad), ("registered within 1 deg", near)):
            for n, l, e, v in lst:
                print(f"  {what}: {n} from {l} ({e['daz']:+.2f}/{e['dp']:+.2f} deg){' vouched' if v else ''}")
        for n, l, m in errs:
            print(f"  error: {n} from {l}: {m}")
        print(f"batches: {len(probes)}; rows: {rows}; registered: {len(bad) + len(near)}, false (> 1 deg): {len(bad)}; "
              f"rows vouched for: {light}; errors: {len(errs)}")
        if check and (bad or errs):
            print(f"FAIL: --modes {mode}: a false registration or an error")
            ok = False
    return ok


if __name__ == "__main__":
    sys.exit(main())
