#!/usr/bin/env python3
"""Independent check of a subject folder's C3D trials with the Python `c3d` package.

Usage: python3 validation/tools/check_c3d.py SUBJECT_DIR

Reads subject.toml and every trial it names, and checks with a reader that shares no code with
ergohand: the spec's marker labels are present (palm markers in every calibration trial, the
plate markers of the measured finger, forearm markers in the wrist trial, every landmark in the
reference trial), POINT:RATE is 100 Hz, POINT:UNITS is mm, and every present sample is finite.
Exits 1 with a one-line reason per problem; prints one summary line per trial otherwise.
"""
import math
import sys
import tomllib
from pathlib import Path

import c3d  # pip install c3d

FINGERS = {"thumb": "T", "index": "I", "middle": "M", "ring": "R", "little": "L"}
JOINTS = ["WRIST", "T_CMC", "T_MCP", "T_IP"] + [
    f"{x}_{j}" for x in "IMRL" for j in ("MCP", "PIP", "DIP")
]
LANDMARKS = (
    [f"PALM_{k}" for k in range(1, 5)]
    + JOINTS
    + [f"{x}_NAIL" for x in "TIMRL"]
    + ["T_MC_1", "T_MC_2", "I_MCP_LAT", "L_MCP_LAT", "WRIST_RAD", "WRIST_ULN"]
)


def links(finger: str) -> list[str]:
    x = FINGERS[finger]
    return [f"{x}_{l}" for l in (("META", "PROX", "DIST") if x == "T" else ("PROX", "MID", "DIST"))]


def expected(key: str) -> list[str]:
    if key == "reference":
        return LANDMARKS
    palm = [f"PALM_{k}" for k in range(1, 5)]
    if key == "wrist":
        return palm + [f"ARM_{k}" for k in range(1, 4)]
    return palm + [f"{l}_{k}" for l in links(key) for k in range(1, 4)]


def main(folder: Path) -> int:
    subject = tomllib.loads((folder / "subject.toml").read_text())
    problems = []
    for key, rel in subject["trials"].items():
        path = folder / rel
        with open(path, "rb") as fh:
            reader = c3d.Reader(fh)
            labels = [l.strip() for l in reader.point_labels]
            rate = reader.point_rate
            units = reader.get("POINT").get("UNITS").string_value.strip()
            frames = 0
            bad = 0
            for _, points, _ in reader.read_frames():
                frames += 1
                for row in points:
                    if row[3] >= 0 and not all(math.isfinite(v) for v in row[:3]):
                        bad += 1
        missing = [m for m in expected(key) if m not in labels]
        if missing:
            problems.append(f"{path}: marker {missing[0]} missing ({len(missing)} in all)")
        if abs(rate - 100.0) > 1e-6:
            problems.append(f"{path}: POINT:RATE is {rate}, expected 100")
        if units != "mm":
            problems.append(f"{path}: POINT:UNITS is '{units}', expected 'mm'")
        if bad:
            problems.append(f"{path}: {bad} present samples are not finite")
        print(f"{key:9s} {len(labels):3d} markers {frames:6d} frames {rate:.0f} Hz {units}")
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
