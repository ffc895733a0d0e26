#!/usr/bin/env python3
"""Peer check of ergohand's C3D codec with ezc3d, which shares no code with it.

Usage:
  python3 validation/tools/c3d_peer.py check DIR   read every DIR/NAME.c3d (written by ergohand)
                                                   with ezc3d against DIR/NAME.json
  python3 validation/tools/c3d_peer.py write DIR   write peer files DIR/NAME.c3d with their
                                                   expected values in DIR/NAME.json

A JSON file holds {"labels": [...], "rate": Hz, "units": "mm", "frames": N, "tolerance_mm": t,
"positions": [[[x, y, z] or null for each frame] for each marker]}, positions in mm (what ergohand
reads, whatever the file's POINT:UNITS). `tests/c3d_peer.rs` runs both commands; it skips when
python3 cannot import ezc3d (`pip install ezc3d c3d`).

ezc3d writes float data only, so the integer-data peer file is written with the Python `c3d`
package when it is installed (and read back with ezc3d too, so that two peers agree on it).
ezc3d takes POINT:FRAMES as an integer only, so it refuses files of more than 65,535 frames
written the standard way (a float POINT:FRAMES); those are checked with the `c3d` package.
Every file checked is also read with the `c3d` package when it is installed.
Exits 1 with one line per problem.
"""
import json
import math
import sys
from pathlib import Path

import ezc3d
import numpy as np

# ezc3d's frame count is a 16-bit integer (see `check`).
EZC3D_MAX_FRAMES = 65_535

UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}


def point_labels(c):
    point = c["parameters"]["POINT"]
    labels = list(point["LABELS"]["value"])
    k = 2
    while f"LABELS{k}" in point:
        labels += list(point[f"LABELS{k}"]["value"])
        k += 1
    return [l.strip() for l in labels]


def compare(name, got, want, tolerance, problems):
    """got, want: positions[marker][frame] as [x, y, z] or None."""
    for m, (gt, wt) in enumerate(zip(got, want)):
        for f, (g, w) in enumerate(zip(gt, wt)):
            if (g is None) != (w is None):
                problems.append(f"{name}: marker {m} frame {f}: {g} where {w} was expected")
                return
            if g is not None and any(abs(a - b) > tolerance * max(1.0, abs(b)) for a, b in zip(g, w)):
                problems.append(f"{name}: marker {m} frame {f}: {g} where {w} was expected")
                return


def ezc3d_positions(c, to_mm):
    """positions[marker][frame] in mm from an ezc3d c3d; a gap is a NaN or a negative residual."""
    points = c["data"]["points"]
    residuals = c["data"]["meta_points"]["residuals"]
    out = []
    for m in range(points.shape[1]):
        track = []
        for f in range(points.shape[2]):
            xyz = points[:3, m, f]
            if residuals[0, m, f] < 0 or not all(math.isfinite(v) for v in xyz):
                track.append(None)
            else:
                track.append([float(v) * to_mm for v in xyz])
        out.append(track)
    return out


def check_with_ezc3d(c3d_path, want, problems):
    c = ezc3d.c3d(str(c3d_path))
    name = c3d_path.name
    labels = point_labels(c)
    if labels != want["labels"]:
        problems.append(f"{name}: labels {labels[:3]}... ({len(labels)}) differ")
    rate = float(c["parameters"]["POINT"]["RATE"]["value"][0])
    if abs(rate - want["rate"]) > 1e-6 * want["rate"]:
        problems.append(f"{name}: POINT:RATE {rate}, expected {want['rate']}")
    units = c["parameters"]["POINT"]["UNITS"]["value"][0].strip()
    if units != want["units"]:
        problems.append(f"{name}: POINT:UNITS '{units}', expected '{want['units']}'")
    frames = c["data"]["points"].shape[2]
    if frames != want["frames"]:
        problems.append(f"{name}: {frames} frames, expected {want['frames']}")
    got = ezc3d_positions(c, UNITS_MM[units] if units in UNITS_MM else 1.0)
    compare(name, got, want["positions"], want["tolerance_mm"], problems)
    return labels, frames


def check_with_pyc3d(c3d_path, want, problems):
    """The Python `c3d` package's frame count and values, when it is installed."""
    try:
        import c3d
    except ImportError:
        return None
    to_mm = UNITS_MM[want["units"]]
    with open(c3d_path, "rb") as fh:
        reader = c3d.Reader(fh)
        tracks = [[] for _ in want["labels"]]
        for _, points, _ in reader.read_frames():
            for m, row in enumerate(points):
                valid = row[3] >= 0 and all(math.isfinite(v) for v in row[:3])
                tracks[m].append([float(v) * to_mm for v in row[:3]] if valid else None)
    frames = len(tracks[0]) if tracks else 0
    if frames != want["frames"]:
        problems.append(f"{c3d_path.name}: the c3d package reads {frames} frames, expected {want['frames']}")
    compare(c3d_path.name + " (c3d package)", tracks, want["positions"], want["tolerance_mm"], problems)
    return frames


def check(folder):
    problems, notes = [], []
    for want_path in sorted(folder.glob("*.json")):
        want = json.loads(want_path.read_text())
        c3d_path = want_path.with_suffix(".c3d")
        try:
            labels, frames = check_with_ezc3d(c3d_path, want, problems)
        except ValueError as e:
            # ezc3d takes POINT:FRAMES as a 16-bit integer only; past 65,535 frames the standard
            # (c3d.org, "Maintaining C3D frame count compatibility") makes it a float.
            if want["frames"] <= EZC3D_MAX_FRAMES or "FRAMES" not in str(e):
                raise
            notes.append(f"{c3d_path.name}: ezc3d {ezc3d.__version__} refuses {want['frames']} frames ({e})")
            pyc3d_frames = check_with_pyc3d(c3d_path, want, problems)
            if pyc3d_frames is None:
                problems.append(f"{c3d_path.name}: the c3d package is needed to check {want['frames']} frames")
            else:
                print(f"c3d package read {c3d_path.name}: {len(want['labels'])} markers, {pyc3d_frames} frames")
            continue
        pyc3d_frames = check_with_pyc3d(c3d_path, want, problems)
        also = "" if pyc3d_frames is None else f"; c3d package {pyc3d_frames} frames"
        print(f"ezc3d {ezc3d.__version__} read {c3d_path.name}: {len(labels)} markers, {frames} frames{also}")
    for n in notes:
        print(f"note: {n}")
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


def expected_json(path, labels, rate, units, positions_mm, tolerance_mm):
    path.write_text(
        json.dumps(
            {
                "labels": labels,
                "rate": rate,
                "units": units,
                "frames": len(positions_mm[0]),
                "tolerance_mm": tolerance_mm,
                "positions": positions_mm,
            }
        )
    )


def trajectories(n_markers, n_frames, seed):
    """Smooth distinct tracks (file units = mm here), shape (3, markers, frames), and a gap mask."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames)[None, :] * 0.05 + np.arange(n_markers)[:, None]
    xyz = np.stack([250.0 * np.sin(t) - 12.5, -700.0 + 30.0 * np.cos(t), 1000.0 + 0.01 * t])
    xyz += rng.normal(0.0, 1.0, xyz.shape)
    gaps = rng.random((n_markers, n_frames)) < 0.05
    return xyz, gaps


def positions_of(xyz, gaps, to_mm):
    return [
        [None if gaps[m, f] else [float(v) * to_mm for v in xyz[:, m, f]] for f in range(xyz.shape[2])]
        for m in range(xyz.shape[1])
    ]


def write_ezc3d(path, labels, rate, units, xyz, gaps, analog=None, residual_gaps=False):
    """Float data (ezc3d's only format). Gaps as NaN (ezc3d's way) or as residual -1."""
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["UNITS"]["value"] = [units]
    # Past 255 labels ezc3d itself continues them in LABELS2, ...
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    points = np.ones((4,) + xyz.shape[1:])
    points[:3] = xyz
    residuals = np.zeros((1,) + xyz.shape[1:])
    if residual_gaps:
        residuals[0][gaps] = -1.0
    else:
        points[:3, gaps] = np.nan
    c["data"]["points"] = points
    c["data"]["meta_points"] = {
        "residuals": residuals,
        "camera_masks": np.zeros((7,) + xyz.shape[1:], dtype=bool),
    }
    if analog is not None:
        channels, per_frame = analog
        frames = xyz.shape[2]
        c["parameters"]["ANALOG"]["RATE"]["value"] = [rate * per_frame]
        c["parameters"]["ANALOG"]["LABELS"]["value"] = tuple(f"EMG{k}" for k in range(channels))
        # Values that would read as markers (and as gaps) if a reader did not skip them.
        c["data"]["analogs"] = -1000.0 - np.arange(channels * frames * per_frame, dtype=float).reshape(
            (1, channels, frames * per_frame)
        )
    c.write(str(path))


def write_pyc3d_integer(path, labels, rate, scale, xyz, gaps, analog):
    """Integer data (positive POINT:SCALE) with the Python `c3d` package; False when absent."""
    try:
        import c3d
    except ImportError:
        return False
    channels, per_frame = analog
    writer = c3d.Writer(point_rate=rate, analog_rate=rate * per_frame, point_scale=scale, point_units="mm  ")
    writer.set_point_labels(labels)
    writer.set_analog_labels([f"FP{k}" for k in range(channels)])
    # Without them ANALOG:SCALE and OFFSET are empty, which crashes ezc3d 1.7.
    writer.set_analog_scales([1.0] * channels)
    writer.set_analog_offsets([0] * channels)
    frames = []
    for f in range(xyz.shape[2]):
        points = np.zeros((xyz.shape[1], 5), dtype=np.float32)
        points[:, :3] = xyz[:, :, f].T
        points[:, 3] = np.where(gaps[:, f], -1.0, 1.0)
        analog_block = (-3.0 - np.arange(channels * per_frame, dtype=np.float32)).reshape((channels, per_frame))
        frames.append((points, analog_block))
    writer.add_frames(frames)
    with open(path, "wb") as fh:
        writer.write(fh)
    return True


def write(folder):
    folder.mkdir(parents=True, exist_ok=True)
    # Float data with analog channels (4 samples per frame), NaN gaps.
    labels = ["PALM_1", "PALM_2", "I_PROX_1", "I_NAIL"]
    xyz, gaps = trajectories(len(labels), 120, 1)
    write_ezc3d(folder / "ezc3d_float_analog.c3d", labels, 150.0, "mm", xyz, gaps, analog=(3, 4))
    expected_json(folder / "ezc3d_float_analog.json", labels, 150.0, "mm", positions_of(xyz, gaps, 1.0), 1e-6)
    # 300 markers (LABELS2), metres, gaps as residual -1.
    labels = [f"M{k:03d}" for k in range(300)]
    xyz, gaps = trajectories(len(labels), 6, 2)
    xyz /= 1000.0
    write_ezc3d(folder / "ezc3d_300_markers_m.c3d", labels, 100.0, "m", xyz, gaps, residual_gaps=True)
    expected_json(folder / "ezc3d_300_markers_m.json", labels, 100.0, "m", positions_of(xyz, gaps, 1000.0), 1e-6)
    # Integer data, scale 0.25 mm, with analog channels: whole counts of a scale exact in binary,
    # so the values are exact whichever way the writer rounds.
    labels = ["PALM_1", "PALM_3", "WRIST"]
    xyz, gaps = trajectories(len(labels), 80, 3)
    xyz = np.round(xyz / 0.25) * 0.25
    if write_pyc3d_integer(folder / "pyc3d_integer_analog.c3d", labels, 120.0, 0.25, xyz, gaps, (2, 5)):
        expected_json(folder / "pyc3d_integer_analog.json", labels, 120.0, "mm", positions_of(xyz, gaps, 1.0), 1e-4)
        # ezc3d must agree with the c3d package on that file.
        problems = []
        want = json.loads((folder / "pyc3d_integer_analog.json").read_text())
        check_with_ezc3d(folder / "pyc3d_integer_analog.c3d", want, problems)
        if problems:
            print("\n".join(problems), file=sys.stderr)
            return 1
    else:
        print("note: the Python c3d package is not installed: no integer-data peer file")
    for p in sorted(folder.glob("*.c3d")):
        print(f"wrote {p.name}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("check", "write"):
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    folder = Path(sys.argv[2])
    sys.exit(check(folder) if sys.argv[1] == "check" else write(folder))
