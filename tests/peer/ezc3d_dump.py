"""Independent check of a C3D file written by ergohand's `write_c3d`, with ezc3d.

Usage: python3 tests/peer/ezc3d_dump.py FILE.c3d   (needs `pip install ezc3d`)

Prints the labels, POINT:RATE, POINT:UNITS, residuals and positions (None for a gap, i.e. a
negative residual, which ezc3d reports as NaN) as ezc3d reads them. Not run by `cargo test`.
"""
import sys

import ezc3d
import numpy as np

c = ezc3d.c3d(sys.argv[1])  # raises on a non-standard parameter section
p = c["parameters"]["POINT"]
labels = p["LABELS"]["value"]
print("labels", labels)
print("rate", p["RATE"]["value"], "header rate", c["header"]["points"]["frame_rate"])
print("units", p["UNITS"]["value"])
print("frames", c["header"]["points"]["first_frame"], c["header"]["points"]["last_frame"])
pts = c["data"]["points"]  # 4 x markers x frames
print("residuals", c["data"]["meta_points"]["residuals"][0].T.tolist())
for m, label in enumerate(labels):
    track = [None if np.isnan(pts[0, m, f]) else pts[:3, m, f].tolist() for f in range(pts.shape[2])]
    print(label, track)
