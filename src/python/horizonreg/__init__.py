"""horizonreg: camera orientation (azimuth, pitch, roll, focal length) of outdoor photos from the
terrain horizon of a digital elevation model, and AR overlays.

    import horizonreg
    site = horizonreg.Site(lat=47.25, lon=9.35, dem=["N47E009.hgt"], agl=2.0)  # built once per position
    r = horizonreg.register("photo.jpg", site)                              # or a numpy BGR array
    print(r["status"], r["azimuth_deg"], r["pitch_deg"], r["roll_deg"], r["hfov_deg"])

Functions: compute_horizon, extract_skyline, register, draw_overlay, read_image, read_manifest,
batch_rows; class Site. Results are the command line's JSON as dicts (numpy arrays for profiles
and skylines); bad input raises ValueError, unreadable files OSError, with the command line's
messages. horizonreg.dask registers an archive on a dask.distributed cluster.
"""
from ._core import (Site, batch_rows, compute_horizon, draw_overlay, extract_skyline, read_image,
                    read_manifest, register)

__all__ = ["Site", "batch_rows", "compute_horizon", "draw_overlay", "extract_skyline", "read_image",
           "read_manifest", "register"]
__version__ = "0.1.0"
