"""Registering a photo archive on a dask.distributed cluster.

The manifest (CSV, JSON or a folder of images, as `horizonreg batch` reads it) is partitioned by
station: every task registers the photos of one camera position, so each worker builds that
station's Site (DEM window and horizon) once. The rows are exactly those `horizonreg batch` writes
(timing aside), in manifest order.

    from horizonreg.dask import register_archive
    rows = register_archive("manifest.csv", dem=["N47E009.hgt"])                    # LocalCluster
    rows = register_archive("manifest.csv", dem_dir="dems/", scheduler="tcp://host:8786")

Command line: python3 -m horizonreg.dask MANIFEST (--dem FILE... | --dem-dir DIR) -o OUT.jsonl
              [--scheduler ADDRESS | --workers N] [--threads-per-worker N] [--stations FILE]
The workers must be able to import horizonreg (PYTHONPATH) and read the photos and DEMs at the
same paths (a shared file system).
"""
import argparse
import collections
import json
import os
import sys

from . import _core

_OPTIONS = ("hfov", "hfov_range", "pinhole", "exif", "step", "refraction", "max_distance", "sea_level_fill",
            "refine_position", "position_sigma", "skylines", "check_every_photo")


def _station_key(item):
    if item["lat"] is not None:
        return ("position", item["lat"], item["lon"], item["alt_m"], item["agl_m"])
    if item["station"]:
        return ("station", item["station"])
    return ("photo", item["image"])  # position from the photo's sensors file or EXIF


def _row_of(item):
    row = {"image": item["image"]}
    for k in ("lat", "lon", "alt_m", "agl_m", "hfov_deg"):
        if item[k] is not None:
            row[k] = item[k]
    for k in ("camera", "sensors", "station"):
        if item[k]:
            row[k] = item[k]
    if item["initial"] is not None:
        row["initial"] = ",".join(repr(v) for v in item["initial"])
    return row


def _register_station(rows, base_dir, dem, dem_dir, threads, options):
    from horizonreg import _core as core  # imported on the worker
    return core.batch_rows(rows, base_dir=base_dir, dem=list(dem), dem_dir=dem_dir, threads=threads, **options)


def register_archive(manifest, dem=(), dem_dir="", stations="", client=None, scheduler=None, n_workers=2,
                     threads_per_worker=1, **options):
    """Registers every photo of `manifest` on a dask cluster: `client` if given, else a Client of
    `scheduler` (an address), else a LocalCluster of n_workers processes. `options` are
    batch_rows's (hfov, hfov_range, pinhole, exif, step, refraction, max_distance,
    sea_level_fill, refine_position, position_sigma, skylines, check_every_photo). Returns the rows (dicts) in
    manifest order."""
    unknown = set(options) - set(_OPTIONS)
    if unknown:
        raise ValueError(f"register_archive: unknown option(s) {sorted(unknown)}")
    if bool(dem) == bool(dem_dir):
        raise ValueError("register_archive: give dem files or dem_dir (one of them)")
    items = _core.read_manifest(manifest, stations)
    base_dir = manifest if os.path.isdir(manifest) else (os.path.dirname(manifest) or ".")
    groups = collections.OrderedDict()
    for i, item in enumerate(items):
        groups.setdefault(_station_key(item), []).append((i, _row_of(item)))
    from dask.distributed import Client, LocalCluster
    own = None
    if client is None:
        if scheduler:
            client = own = Client(scheduler)
        else:
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=threads_per_worker, processes=True,
                                   dashboard_address=None)
            client = own = Client(cluster)
    try:
        futures = [client.submit(_register_station, [r for _, r in g], base_dir, tuple(dem), dem_dir,
                                 threads_per_worker, options, pure=False) for g in groups.values()]
        results = client.gather(futures)
    finally:
        if own is not None:
            cluster = own.cluster
            own.close()
            if cluster is not None:
                cluster.close()
    out = [None] * len(items)
    for g, rows in zip(groups.values(), results):
        for (i, _), row in zip(g, rows):
            out[i] = row
    return out


def main(argv=None):
    p = argparse.ArgumentParser(prog="python3 -m horizonreg.dask", description=__doc__.split("\n\n")[0])
    p.add_argument("manifest")
    p.add_argument("--dem", action="append", default=[])
    p.add_argument("--dem-dir", default="")
    p.add_argument("--stations", default="")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--scheduler")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--threads-per-worker", type=int, default=1)
    p.add_argument("--refine-position", action="store_true",
                   help="also estimate each photo's position (as horizonreg batch --refine-position)")
    p.add_argument("--skylines", action="store_true",
                   help="rows also carry each photo's skyline (as horizonreg batch --skylines)")
    p.add_argument("--check-every-photo", action="store_true",
                   help="the position check's wide look on every photo (as horizonreg batch --check-every-photo)")
    a = p.parse_args(argv)
    try:
        rows = register_archive(a.manifest, dem=a.dem, dem_dir=a.dem_dir, stations=a.stations, scheduler=a.scheduler,
                                n_workers=a.workers, threads_per_worker=a.threads_per_worker,
                                refine_position=a.refine_position, skylines=a.skylines,
                                check_every_photo=a.check_every_photo)
    except (ValueError, OSError) as e:
        print(f"horizonreg.dask: {e}", file=sys.stderr)
        return 2
    tmp = a.output + ".tmp"
    with open(tmp, "w") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")
    os.replace(tmp, a.output)
    print(f"horizonreg.dask: {len(rows)} photos, {sum(r['status'] == 'registered' for r in rows)} registered; "
          f"rows in {a.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
