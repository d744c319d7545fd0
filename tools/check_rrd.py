#!/usr/bin/env python3
"""Checks a recording of `photopose viewer` against the poses the estimator published.

    python3 tools/check_rrd.py RUN.rrd POSES.json

POSES.json holds {"poses": [...], "truths": [...]}, each pose as
{"frame_id", "capture_time_ns", "position_mm": [x, y, z], "fitness", "status"}.
It opens the recording with rerun-sdk (pip install rerun-sdk==0.36.3, the version of the
Rust SDK photopose logs with) and checks that the entities and time lines are there and
that the images are JPEGs and every logged x, y, z, fitness and status equals the
published pose of its frame,
for most of the published poses. Prints what it matched; exits 1 naming the first
problem.
"""

import json
import sys
from collections import defaultdict

import pyarrow as pa
from rerun.experimental import RrdReader

ENTITIES = [
    "/world/camera",
    "/world/camera/image",
    "/world/camera/image/estimate",
    "/world/estimate",
    "/world/trajectory/estimate",
    "/series/x/estimate",
    "/series/y/estimate",
    "/series/z/estimate",
    "/series/fitness",
    "/series/status",
    "/series/latency_ms",
    "/series/dropped",
]
TRUTH_ENTITIES = ["/world/truth", "/series/x/truth", "/world/trajectory/truth"]
# Share of the published poses the recording must hold: the viewer takes every pose
# (it drains its subscriber at each image), but it starts and stops a little apart from
# the test's own subscriber.
MIN_SHARE = 0.95


def fail(message):
    print(f"check_rrd: {message}", file=sys.stderr)
    sys.exit(1)


def read(path):
    """entity -> list of rows {column: value}, and entity -> set of components."""
    rows = defaultdict(list)
    components = defaultdict(set)
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n not in ("rerun.controls.RowId", "log_time")]
        columns = {}
        for name in names:
            column = batch.column(name)
            if pa.types.is_duration(column.type) or pa.types.is_timestamp(column.type):
                column = column.cast(pa.int64())
            columns[name] = column.to_pylist()
            if ":" in name:
                components[chunk.entity_path].add(name)
        for i in range(batch.num_rows):
            rows[chunk.entity_path].append({n: columns[n][i] for n in names})
    return rows, components


def series(rows, entity):
    """frame -> (value, capture_time) of a Scalars entity."""
    out = {}
    for r in rows.get(entity, []):
        if "frame" not in r or "capture_time" not in r:
            fail(f"{entity}: a row without the frame or capture_time time line: {sorted(r)}")
        values = r.get("Scalars:scalars")
        if values:
            out[r["frame"]] = (values[0], r["capture_time"])
    return out


def main():
    if len(sys.argv) != 3:
        fail("usage: check_rrd.py RUN.rrd POSES.json")
    path, poses_path = sys.argv[1], sys.argv[2]
    try:
        published = json.load(open(poses_path))
    except (OSError, ValueError) as e:
        fail(f"{poses_path}: {e}")
    try:
        rows, components = read(path)
    except Exception as e:  # rerun raises several kinds for a bad file
        fail(f"{path}: cannot read the recording: {e}")
    poses = {p["frame_id"]: p for p in published["poses"]}
    expected = ENTITIES + (TRUTH_ENTITIES if published["truths"] else [])
    for entity in expected:
        if entity not in rows:
            fail(f"{path}: no entity {entity} (has {sorted(rows)})")
    for entity, component in [
        ("/world/camera/image", "EncodedImage:blob"),
        ("/world/camera/image", "Pinhole:image_from_camera"),
        ("/world/estimate", "Boxes3D:half_sizes"),
        ("/world/camera/image/estimate", "LineStrips2D:strips"),
    ]:
        if component not in components[entity]:
            fail(f"{path}: {entity} has no {component} (has {sorted(components[entity])})")
    images = [r for r in rows["/world/camera/image"] if r.get("EncodedImage:blob")]
    if len(images) < 5:
        fail(f"{path}: {len(images)} images, expected at least 5")
    for r in images:
        if r["EncodedImage:blob"][0][:2] != [0xFF, 0xD8] or r.get("EncodedImage:media_type") != ["image/jpeg"]:
            fail(f"{path}: an image at frame {r.get('frame')} is not a JPEG")
    fields = {
        "/series/x/estimate": lambda p: p["position_mm"][0],
        "/series/y/estimate": lambda p: p["position_mm"][1],
        "/series/z/estimate": lambda p: p["position_mm"][2],
        "/series/fitness": lambda p: p["fitness"],
        "/series/status": lambda p: float(p["status"]),
    }
    matched = None
    for entity, field in fields.items():
        logged = series(rows, entity)
        for frame, (value, capture) in logged.items():
            p = poses.get(frame)
            if p is None:
                continue
            if value != field(p):
                fail(f"{entity} at frame {frame}: {value!r}, but the estimator published {field(p)!r}")
            if capture != p["capture_time_ns"]:
                fail(f"{entity} at frame {frame}: capture_time {capture}, published {p['capture_time_ns']}")
        common = set(logged) & set(poses)
        matched = len(common) if matched is None else min(matched, len(common))
    if matched < MIN_SHARE * len(poses) or matched == 0:
        fail(f"{path}: {matched} of {len(poses)} published poses are in the recording (need {MIN_SHARE:.0%})")
    truths = {t["frame_id"]: t for t in published["truths"]}
    truth_x = series(rows, "/series/x/truth") if truths else {}
    for frame, (value, _) in truth_x.items():
        if frame in truths and value != truths[frame]["position_mm"][0]:
            fail(f"/series/x/truth at frame {frame}: {value!r}, published {truths[frame]['position_mm'][0]!r}")
    print(
        f"check_rrd: {path}: {len(rows)} entities, {len(images)} images; "
        f"{matched} of {len(poses)} published poses equal in x, y, z, fitness and status; "
        f"{len(set(truth_x) & set(truths))} truths equal in x"
    )


if __name__ == "__main__":
    main()
