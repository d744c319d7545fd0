#!/usr/bin/env python3
"""Check `photopose bridge` the way a ROS 2 node on rmw_zenoh_cpp would see it.

A ROS-2-like subscriber made of PyPI packages only: ``eclipse-zenoh`` for the transport,
``rosbags`` for CDR decoding and the RIHS01 type hashes, ``iceoryx2`` for the poses the
bridge reads. No ROS 2 installation is needed::

    pip install eclipse-zenoh==1.10.2 rosbags==0.11.9 iceoryx2==0.10.0

For ``--seconds`` it receives the pose sets on ``photopose/poses`` over iceoryx2 and the
bridge's ``/photopose/<object>/pose`` (``geometry_msgs/msg/PoseStamped``) and
``/photopose/<object>/status`` (``diagnostic_msgs/msg/DiagnosticStatus``) over Zenoh,
pairs each Zenoh pose with the iceoryx2 pose of the same object and capture time, and
checks:

- the key expressions ``<domain>/photopose/<object>/<pose|status>/<DDS type>/<RIHS01>``,
  the hash being rosbags' for Jazzy;
- each message decodes with rosbags, in metres, bit for bit ``mm / 1000``, the
  quaternion reordered to x, y, z, w, ``header.frame_id`` as given;
- the attachment: 33 bytes, sequence numbers increasing per publisher (GID), a 16-byte GID;
- the liveliness tokens ``@ros2_lv/...`` of the node and of each publisher.

It prints one JSON summary (received over each side, share, largest difference, the
latency the bridge adds: Zenoh arrival minus iceoryx2 arrival in this process, p50/p99)
and exits 1 with one ``error:`` line when a check fails.

Usage (the bridge connects to this client, so no multicast is needed)::

    python3 tools/ros2_pose_client.py --listen tcp/127.0.0.1:7448 --seconds 10
    photopose bridge --connect tcp/127.0.0.1:7448 --no-multicast
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import sys
import threading
import time
from typing import Optional

POSES_SERVICE = "photopose/poses"
NODE_NAME = "photopose_bridge"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
STATUS_TYPE = "diagnostic_msgs/msg/DiagnosticStatus"
STATUS_NAMES = {0: "tracking", 1: "searching", 2: "lost"}
LEVELS = {0: 0, 1: 1, 2: 2}  # status code -> DiagnosticStatus level (OK, WARN, ERROR)
# A Zenoh pose and an iceoryx2 pose are the same when their times differ by less than
# this (frames are at least ~16 ms apart; the two clock offsets differ by microseconds).
PAIR_TOLERANCE_NS = 1_000_000


class Failure(Exception):
    """A check failed: the message is the one line printed."""


def dds_name(ros_name: str) -> str:
    pkg, kind, name = ros_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


# iceoryx2: the pose sets, through tools/pose_client.py (wire contract version 2).

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pose_client import ClientError, PoseMsg, PoseSubscriber  # noqa: E402


# ----------------------------------------------------------------------------------------
# Zenoh: what a ROS 2 subscriber on rmw_zenoh receives.


def zenoh_session(args):
    import zenoh

    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false" if args.no_multicast else "true")
    if args.listen:
        config.insert_json5("listen/endpoints", json.dumps(args.listen))
    if args.connect:
        config.insert_json5("connect/endpoints", json.dumps(args.connect))
    return zenoh.open(config)


def parse_attachment(raw: bytes) -> tuple[int, int, bytes]:
    """rmw_zenoh's attachment in zenoh-ext's serialisation: i64 sequence number, i64
    source timestamp, then the GID as a sequence (LEB128 length 16, 16 bytes)."""
    if len(raw) != 33 or raw[16] != 16:
        raise Failure(f"attachment of {len(raw)} bytes ({raw.hex()}), expected 8 + 8 + 1 + 16")
    seq = int.from_bytes(raw[0:8], "little", signed=True)
    stamp = int.from_bytes(raw[8:16], "little", signed=True)
    try:  # the same bytes through zenoh-ext's own deserialiser
        import zenoh
        from zenoh.ext import Int64, UInt8, z_deserialize

        s2, t2, gid = z_deserialize(tuple[Int64, Int64, list[UInt8]], zenoh.ZBytes(raw))
        if (s2, t2, bytes(gid)) != (seq, stamp, raw[17:]):
            raise Failure("attachment: zenoh-ext reads other values than the byte layout")
    except ImportError:
        pass
    return seq, stamp, raw[17:]


class Received:
    """Zenoh samples as they arrive (the callback runs on a Zenoh thread)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.samples: list[tuple[int, str, bytes, Optional[bytes]]] = []

    def __call__(self, sample) -> None:
        now = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        item = (now, str(sample.key_expr), sample.payload.to_bytes(), attachment)
        with self.lock:
            self.samples.append(item)

    def count(self) -> int:
        with self.lock:
            return len(self.samples)

    def take(self) -> list:
        with self.lock:
            out, self.samples = self.samples, []
        return out


# ----------------------------------------------------------------------------------------
# Checks.


class Checker:
    def __init__(self, typestore, domain: int, frame_id: str):
        self.ts = typestore
        self.domain = domain
        self.frame_id = frame_id
        self.hashes = {t: typestore.hash_rihs01(t) for t in (POSE_TYPE, STATUS_TYPE)}
        self.key_re = re.compile(
            rf"^{domain}/photopose/([A-Za-z][A-Za-z0-9_]*)/(pose|status)/([^/]+)/(RIHS01_[0-9a-f]{{64}})$"
        )
        self.sequences: dict[tuple[str, bytes], int] = {}
        self.gids: dict[str, set[bytes]] = {}

    def key(self, key: str) -> tuple[str, str]:
        m = self.key_re.match(key)
        if not m:
            raise Failure(f"key expression {key} is not <domain>/photopose/<object>/<pose|status>/<type>/<RIHS01>")
        obj, leaf, type_name, type_hash = m.groups()
        ros_type = POSE_TYPE if leaf == "pose" else STATUS_TYPE
        if type_name != dds_name(ros_type) or type_hash != self.hashes[ros_type]:
            raise Failure(f"{key}: expected type {dds_name(ros_type)} and hash {self.hashes[ros_type]}")
        return obj, leaf

    def attachment(self, key: str, raw: Optional[bytes]) -> int:
        if raw is None:
            raise Failure(f"{key}: sample without attachment")
        seq, stamp, gid = parse_attachment(raw)
        # Per publisher (GID): a restarted bridge is a new publisher, counting from 1 again.
        last = self.sequences.get((key, gid), 0)
        if seq <= last:
            raise Failure(f"{key}: sequence number {seq} after {last} from the same publisher")
        if abs(stamp - time.time_ns()) > 60_000_000_000:
            raise Failure(f"{key}: source timestamp {stamp} ns is not CLOCK_REALTIME now")
        self.gids.setdefault(key, set()).add(gid)
        self.sequences[(key, gid)] = seq
        return seq

    def pose_matches(self, msg, ice: PoseMsg) -> list[str]:
        """Where a decoded PoseStamped differs from the iceoryx2 pose (bit for bit)."""
        want = [v / 1000.0 for v in ice.position_mm]
        w, x, y, z = ice.orientation_wxyz
        got_p = [msg.pose.position.x, msg.pose.position.y, msg.pose.position.z]
        q = msg.pose.orientation
        bad = []
        if got_p != want:
            bad.append(f"position {got_p} m vs {want}")
        if [q.x, q.y, q.z, q.w] != [x, y, z, w]:
            bad.append(f"orientation {[q.x, q.y, q.z, q.w]} vs {[x, y, z, w]}")
        if msg.header.frame_id != self.frame_id:
            bad.append(f"frame_id {msg.header.frame_id!r}")
        return bad

    def status_matches(self, msg, obj: str, ice: PoseMsg) -> list[str]:
        values = {kv.key: kv.value for kv in msg.values}
        bad = []
        if msg.level != LEVELS.get(ice.status, 2) or msg.message != STATUS_NAMES.get(ice.status, "unknown"):
            bad.append(f"level {msg.level} / {msg.message!r} for status {ice.status}")
        if msg.name != obj:
            bad.append(f"name {msg.name!r}")
        want = {
            "fitness": ice.fitness,
            "generations": ice.generations,
            "size_x_m": ice.size_mm[0] / 1000.0,
            "size_y_m": ice.size_mm[1] / 1000.0,
        }
        for k, v in want.items():
            if k not in values or type(v)(values[k]) != v:
                bad.append(f"{k} {values.get(k)!r} vs {v!r}")
        return bad


def check_liveliness(session, checker: Checker, objects: set[str]) -> dict:
    """The node's and the publishers' tokens, in rmw_zenoh's format."""
    keys = []
    for reply in session.liveliness().get("@ros2_lv/**", timeout=5.0):
        if reply.ok is not None:
            keys.append(str(reply.ok.key_expr))
    problems = []
    node = [k for k in keys if k.split("/")[5:6] == ["NN"] and k.endswith("/" + NODE_NAME)]
    if len(node) != 1:
        problems.append(f"{len(node)} node tokens of {NODE_NAME} among {keys}")
    else:
        p = node[0].split("/")
        if len(p) != 9 or p[0] != "@ros2_lv" or p[1] != str(checker.domain) or p[3] != p[4] or p[6:8] != ["%", "%"]:
            problems.append(f"node token {node[0]}")
    publishers = {}
    for k in keys:
        p = k.split("/")
        if len(p) == 13 and p[5] == "MP" and p[8] == NODE_NAME:
            publishers[p[9]] = p
    for obj in sorted(objects):
        for leaf, ros_type in (("pose", POSE_TYPE), ("status", STATUS_TYPE)):
            topic = f"%photopose%{obj}%{leaf}"
            p = publishers.get(topic)
            if p is None:
                problems.append(f"no publisher token for /photopose/{obj}/{leaf}")
                continue
            qos = p[12].split(":")
            if (
                p[1] != str(checker.domain)
                or (node and p[2:4] != node[0].split("/")[2:4])
                or p[10] != dds_name(ros_type)
                or p[11] != checker.hashes[ros_type]
                or len(qos) != 6
                or len(qos[2].split(",")) != 2
            ):
                problems.append(f"publisher token {'/'.join(p)}")
    return {"ok": not problems, "node_tokens": len(node), "publisher_tokens": len(publishers), "problems": problems}


def percentile(values: list[float], q: float) -> Optional[float]:
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


# ----------------------------------------------------------------------------------------


def collect(args, session, subscriber, received: Received):
    """Waits for the bridge's first message, then collects for ``--seconds``."""
    start = time.monotonic()
    while received.count() == 0:
        if time.monotonic() - start > args.wait:
            raise Failure(f"no message from the bridge over Zenoh within {args.wait} s")
        while subscriber.receive() is not None:
            pass
        time.sleep(0.01)
    waited = time.monotonic() - start
    received.take()  # only what arrives from now on counts
    while subscriber.receive() is not None:
        pass
    ice = []  # (arrival ns, object, pose)
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        got = subscriber.receive()
        if got is None:
            time.sleep(0.0002)
            continue
        now = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        ice += [(now, pose.object, pose) for pose in got]
    time.sleep(0.5)  # the last poses' way through the bridge
    return waited, ice, received.take()


def evaluate(args, checker: Checker, ice, zsamples, offset_ns: int) -> dict:
    by_time = {}
    for arrival, obj, pose in ice:
        by_time.setdefault(obj, []).append((pose.capture_time_ns, arrival, pose))
    paired, mismatches, latencies, from_publish, statuses = set(), [], [], [], 0
    by_frame = {(obj, p.frame_id): p for _, obj, p in ice}
    zenoh_poses = 0
    for arrival, key, payload, attachment in zsamples:
        obj, leaf = checker.key(key)
        checker.attachment(key, attachment)
        if leaf == "status":
            msg = checker.ts.deserialize_cdr(payload, STATUS_TYPE)
            values = {kv.key: kv.value for kv in msg.values}
            ice_pose = by_frame.get((obj, int(values.get("frame_id", -1))))
            if ice_pose is not None:
                statuses += 1
                mismatches += [f"{obj} status: {b}" for b in checker.status_matches(msg, obj, ice_pose)]
            continue
        zenoh_poses += 1
        msg = checker.ts.deserialize_cdr(payload, POSE_TYPE)
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        capture = stamp - offset_ns
        candidates = by_time.get(obj, [])
        best = min(candidates, key=lambda c: abs(c[0] - capture), default=None)
        if best is None or abs(best[0] - capture) > PAIR_TOLERANCE_NS:
            continue  # published before the window opened, or not seen over iceoryx2
        if (obj, best[2].frame_id) in paired:
            mismatches.append(f"{obj} frame {best[2].frame_id} received twice over Zenoh")
            continue
        paired.add((obj, best[2].frame_id))
        mismatches += [f"{obj} frame {best[2].frame_id}: {b}" for b in checker.pose_matches(msg, best[2])]
        latencies.append((arrival - best[1]) / 1e6)
        from_publish.append((arrival - best[2].publish_time_ns) / 1e6)
    share = len(paired) / len(ice) if ice else 0.0
    return {
        "ipc_poses": len(ice),
        "zenoh_poses": zenoh_poses,
        "paired": len(paired),
        "share": round(share, 4),
        "status_messages_checked": statuses,
        "objects": sorted({obj for _, obj, _ in ice}),
        "bit_equal": not mismatches,
        "max_abs_diff": 0.0 if not mismatches else None,
        "mismatches": mismatches[:5],
        "latency_ms": {
            "p50": percentile(latencies, 0.5),
            "p99": percentile(latencies, 0.99),
            "max": max(latencies, default=None),
            "mean": statistics.fmean(latencies) if latencies else None,
        },
        "latency_from_estimator_publish_ms": {
            "p50": percentile(from_publish, 0.5),
            "p99": percentile(from_publish, 0.99),
        },
    }


def realtime_offset_ns() -> int:
    best = None
    for _ in range(5):
        a = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        r = time.clock_gettime_ns(time.CLOCK_REALTIME)
        b = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        if best is None or b - a < best[0]:
            best = (b - a, r - (a + b) // 2)
    return best[1]


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(description="Check photopose bridge as a ROS 2 subscriber would.")
    parser.add_argument("--listen", action="append", default=[], help="Zenoh endpoint to listen on")
    parser.add_argument("--connect", action="append", default=[], help="Zenoh endpoint to connect to")
    parser.add_argument("--no-multicast", action="store_true", help="no UDP multicast scouting")
    parser.add_argument("--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID") or 0))
    parser.add_argument("--frame-id", default="hand")
    parser.add_argument("--service", default=POSES_SERVICE)
    parser.add_argument("--seconds", type=float, default=10.0, help="measurement window")
    parser.add_argument("--wait", type=float, default=30.0, help="seconds to wait for the bridge")
    parser.add_argument("--min-share", type=float, default=0.95)
    args = parser.parse_args(argv)
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        import zenoh  # noqa: F401
        from rosbags.typesys import Stores, get_typestore

        import iceoryx2  # noqa: F401
    except ImportError as e:
        print(f"error: {e} (pip install eclipse-zenoh==1.10.2 rosbags==0.11.9 iceoryx2==0.10.0)", file=sys.stderr)
        return 2
    checker = Checker(get_typestore(Stores.ROS2_JAZZY), args.domain, args.frame_id)
    try:
        subscriber = PoseSubscriber(args.service, node_name="photopose-ros2-check")
        session = zenoh_session(args)
        received = Received()
        subs = [
            session.declare_subscriber(f"{args.domain}/photopose/*/{leaf}/**", received)
            for leaf in ("pose", "status")
        ]
        waited, ice, zsamples = collect(args, session, subscriber, received)
        summary = evaluate(args, checker, ice, zsamples, realtime_offset_ns())
        summary["waited_s"] = round(waited, 3)
        summary["liveliness"] = check_liveliness(session, checker, set(summary["objects"]))
        summary["type_hashes"] = checker.hashes
        print(json.dumps(summary), flush=True)
        for s in subs:
            s.undeclare()
        session.close()
        subscriber.close()
        if summary["ipc_poses"] == 0:
            raise Failure("no pose over iceoryx2 during the window")
        if summary["share"] < args.min_share:
            raise Failure(f"only {summary['paired']} of {summary['ipc_poses']} iceoryx2 poses arrived over Zenoh ({summary['share']:.1%})")
        if not summary["bit_equal"]:
            raise Failure(f"Zenoh messages differ from the iceoryx2 poses: {summary['mismatches'][0]}")
        if not summary["liveliness"]["ok"]:
            raise Failure(f"liveliness tokens: {summary['liveliness']['problems'][0]}")
    except (Failure, ClientError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
