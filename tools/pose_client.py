#!/usr/bin/env python3
"""Subscribe to photopose poses over iceoryx2 shared memory, from Python.

photopose publishes one ``PoseSet`` per processed frame on ``photopose/poses``: the pose
of every tracked object, each named (and the ground truth of synthetic frames on
``photopose/truth``, same type). This client needs no Rust, only the iceoryx2 Python
bindings of the same version as the service::

    pip install iceoryx2==0.10.0

Usage::

    python3 tools/pose_client.py                          # poses, one readable line each
    python3 tools/pose_client.py --service photopose/truth --count 10
    python3 tools/pose_client.py --json --seconds 5       # one JSON object per line
    python3 tools/pose_client.py --object cup             # one object's poses only

Options: ``--service NAME`` (default ``photopose/poses``), ``--count N`` (exit after N
poses; exit status 1 if ``--seconds`` ran out first), ``--seconds S`` (exit after S
seconds), ``--object NAME``, ``--json``. Ctrl-C or SIGTERM ends it cleanly. The client may start before or
after the publisher.

As a library (copies of the messages, shared memory released at once)::

    from pose_client import subscribe
    for pose in subscribe("photopose/poses"):
        print(pose.object, pose.frame_id, pose.position(), pose.status_name)

The payload is the C struct ``PoseSet`` below (version 2 of the contract, iceoryx2 type
name ``PhotoposePoseV2``, no user header): 1160 bytes, alignment 8: ``count`` (u32),
``reserved`` (u32), then 8 ``ObjectPose`` of 144 bytes each, a NUL-padded name of 32
bytes and the 112-byte ``PoseMsg`` of version 1. A C++ client declares standard-layout
structs with the same fields and the same type name. A client still built for version 1
(``PhotoposePose``) is refused by iceoryx2 with an incompatible-types error.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import sys
import time
from typing import Iterator, Optional

try:
    import iceoryx2 as iox2
except ImportError:  # reported when a subscriber is created, so PoseMsg stays importable
    iox2 = None

POSES_SERVICE = "photopose/poses"
TRUTH_SERVICE = "photopose/truth"
ICEORYX2_VERSION = "0.10.0"
INSTALL_HINT = f"pip install iceoryx2=={ICEORYX2_VERSION}"

# Service settings of src/ipc.rs (Ipc::poses). A client that happens to start first
# creates the service, and the Rust processes then open it with these requirements:
# created with iceoryx2's defaults instead (8 subscribers, buffer 2, no history), the
# photopose publisher fails with DoesNotSupportRequestedAmountOfSubscribers.
SUBSCRIBER_MAX_BUFFER_SIZE = 64
HISTORY_SIZE = 1
ENABLE_SAFE_OVERFLOW = True
MAX_PUBLISHERS = 2
MAX_SUBSCRIBERS = 16

STATUS_NAMES = {0: "tracking", 1: "searching", 2: "lost"}


class PoseMsg(ctypes.Structure):
    """One pose of the model in the hand frame; the ``#[repr(C)]`` PoseMsg of photopose."""

    _fields_ = [
        ("frame_id", ctypes.c_uint64),
        ("capture_time_ns", ctypes.c_uint64),  # CLOCK_MONOTONIC at exposure/reception
        ("publish_time_ns", ctypes.c_uint64),  # CLOCK_MONOTONIC at publication
        ("position_mm", ctypes.c_double * 3),  # model origin in the hand frame
        ("orientation_wxyz", ctypes.c_double * 4),  # Hamilton quaternion, w >= 0
        ("size_mm", ctypes.c_double * 2),  # L, B
        ("fitness", ctypes.c_double),  # 0..2
        ("generations", ctypes.c_uint32),
        ("status", ctypes.c_uint32),  # 0 tracking, 1 searching, 2 lost
    ]

    def position(self) -> list[float]:
        return list(self.position_mm)

    def orientation(self) -> list[float]:
        return list(self.orientation_wxyz)

    def size(self) -> list[float]:
        return list(self.size_mm)

    @property
    def status_name(self) -> str:
        return STATUS_NAMES.get(self.status, f"status{self.status}")

    def age_ms(self, now_ns: Optional[int] = None) -> float:
        """Milliseconds from capture to ``now_ns`` (default: now, CLOCK_MONOTONIC)."""
        if now_ns is None:
            now_ns = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        return (now_ns - self.capture_time_ns) * 1e-6

    def to_dict(self) -> dict:
        """The fields as plain Python values (floats round-trip exactly through JSON)."""
        return {
            "object": getattr(self, "object", ""),
            "frame_id": self.frame_id,
            "capture_time_ns": self.capture_time_ns,
            "publish_time_ns": self.publish_time_ns,
            "position_mm": self.position(),
            "orientation_wxyz": self.orientation(),
            "size_mm": self.size(),
            "fitness": self.fitness,
            "generations": self.generations,
            "status": self.status,
        }


MAX_OBJECTS = 8
NAME_LEN = 32


class ObjectPose(ctypes.Structure):
    """One object's pose in a PoseSet: its NUL-padded name and its PoseMsg."""

    _fields_ = [("name", ctypes.c_uint8 * NAME_LEN), ("pose", PoseMsg)]

    def object_name(self) -> str:
        raw = bytes(self.name).split(b"\0", 1)[0]
        return raw.decode("utf-8", errors="replace")


class PoseSet(ctypes.Structure):
    """The poses of every object in one frame (``objects[:count]``)."""

    _fields_ = [
        ("count", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("objects", ObjectPose * MAX_OBJECTS),
    ]

    @staticmethod
    def type_name() -> str:
        """The iceoryx2 type name (iceoryx2.get_type_name calls this)."""
        return "PhotoposePoseV2"

    def poses(self) -> list[PoseMsg]:
        """Copies of the objects' poses, each with its name as ``.object``."""
        out = []
        for o in self.objects[: min(self.count, MAX_OBJECTS)]:
            pose = PoseMsg.from_buffer_copy(o.pose)
            pose.object = o.object_name()
            out.append(pose)
        return out


def _check_layout() -> None:
    expected = {
        "frame_id": 0,
        "capture_time_ns": 8,
        "publish_time_ns": 16,
        "position_mm": 24,
        "orientation_wxyz": 48,
        "size_mm": 80,
        "fitness": 96,
        "generations": 104,
        "status": 108,
    }
    offsets = {name: getattr(PoseMsg, name).offset for name, _ in PoseMsg._fields_}
    # Not `assert`: python -O would drop it, and a wrong layout reads garbage.
    if ctypes.sizeof(PoseMsg) != 112 or ctypes.alignment(PoseMsg) != 8 or offsets != expected:
        raise AssertionError(
            f"PoseMsg layout: size {ctypes.sizeof(PoseMsg)}, align "
            f"{ctypes.alignment(PoseMsg)}, offsets {offsets}; the contract is 112, 8, {expected}"
        )
    set_layout = (ctypes.sizeof(ObjectPose), ObjectPose.pose.offset, ctypes.sizeof(PoseSet), PoseSet.objects.offset)
    if set_layout != (144, 32, 1160, 8) or ctypes.alignment(PoseSet) != 8:
        raise AssertionError(f"PoseSet layout {set_layout}; the contract is (144, 32, 1160, 8)")


_check_layout()


class ClientError(RuntimeError):
    """The subscriber cannot be set up (package missing, service incompatible, ...)."""


class PoseSubscriber:
    """An iceoryx2 node with one subscriber to a pose service.

    ``receive()`` returns copies of the poses of the oldest set not yet received (a list,
    one per object), or None;
    ``wait(seconds)`` sleeps and returns False once the process was asked to terminate
    (SIGINT, SIGTERM); ``poses()`` iterates. Use as a context manager, or call ``close()``.
    """

    def __init__(self, service: str = POSES_SERVICE, node_name: str = "photopose-py-client"):
        if iox2 is None:
            raise ClientError(f"the Python package iceoryx2 is missing: {INSTALL_HINT}")
        iox2.set_log_level(iox2.LogLevel.Error)
        self.service = service
        self.terminated = False
        try:
            self._node = (
                iox2.NodeBuilder.new()
                .name(iox2.NodeName.new(node_name))
                .signal_handling_mode(iox2.SignalHandlingMode.HandleTerminationRequests)
                .create(iox2.ServiceType.Ipc)
            )
        except Exception as e:  # noqa: BLE001 - iceoryx2 errors are plain Exceptions
            raise ClientError(f"cannot create the iceoryx2 node: {e!r}") from e
        try:
            self._node.try_cleanup_dead_nodes()
        except Exception:  # noqa: BLE001 - best effort, like the Rust processes
            pass
        try:
            self._service = (
                self._node.service_builder(iox2.ServiceName.new(service))
                .publish_subscribe(PoseSet)  # type name, size 1160, alignment 8; header ()
                .subscriber_max_buffer_size(SUBSCRIBER_MAX_BUFFER_SIZE)
                .history_size(HISTORY_SIZE)
                .enable_safe_overflow(ENABLE_SAFE_OVERFLOW)
                .max_publishers(MAX_PUBLISHERS)
                .max_subscribers(MAX_SUBSCRIBERS)
                .open_or_create()
            )
            self._subscriber = self._service.subscriber_builder().create()
        except Exception as e:  # noqa: BLE001
            self.close()
            raise ClientError(f"cannot open {service}: {e!r}") from e

    def receive(self) -> Optional[list[PoseMsg]]:
        sample = self._subscriber.receive()
        if sample is None:
            return None
        poses = PoseSet()
        ctypes.memmove(ctypes.addressof(poses), sample.payload_ptr, ctypes.sizeof(PoseSet))
        sample.delete()  # give the shared-memory slot back at once
        return poses.poses()

    def wait(self, seconds: float) -> bool:
        try:
            self._node.wait(iox2.Duration.from_secs_f64(seconds))
            return True
        except iox2.NodeWaitFailure:  # Interrupt / TerminationRequest
            return False

    def poses(self, seconds: Optional[float] = None, poll_seconds: float = 0.002) -> Iterator[PoseMsg]:
        """Yields poses (each object's, in set order) until ``seconds`` have passed (forever
        if None) or the process is asked to terminate (then ``terminated`` is True). The
        publisher does not signal new samples, so this polls every ``poll_seconds``.
        """
        deadline = None if seconds is None else time.monotonic() + seconds
        while deadline is None or time.monotonic() < deadline:
            poses = self.receive()
            if poses is not None:
                yield from poses
                continue
            timeout = poll_seconds
            if deadline is not None:
                timeout = max(0.0, min(timeout, deadline - time.monotonic()))
            if not self.wait(timeout):
                self.terminated = True
                return

    def close(self) -> None:
        sub = getattr(self, "_subscriber", None)
        if sub is not None:
            sub.delete()
        # Dropping the last references releases the service and the node (in this order).
        self._subscriber = None
        self._service = None
        self._node = None

    def __enter__(self) -> "PoseSubscriber":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def subscribe(
    service: str = POSES_SERVICE,
    seconds: Optional[float] = None,
    poll_seconds: float = 0.002,
) -> Iterator[PoseMsg]:
    """Yields the poses published on ``service`` until ``seconds`` have passed (forever if
    None) or the process is asked to terminate. Raises ClientError if it cannot subscribe.
    """
    with PoseSubscriber(service) as sub:
        yield from sub.poses(seconds, poll_seconds)


def format_line(pose: PoseMsg, now_ns: int) -> str:
    x, y, z = pose.position_mm
    w, qx, qy, qz = pose.orientation_wxyz
    length, breadth = pose.size_mm
    return (
        f"{getattr(pose, 'object', ''):10s} frame {pose.frame_id:6d} {pose.status_name:9s} "
        f"pos [{x:8.2f} {y:8.2f} {z:8.2f}] mm  "
        f"q [{w:7.4f} {qx:7.4f} {qy:7.4f} {qz:7.4f}]  "
        f"size {length:6.1f} x {breadth:6.1f} mm  "
        f"fitness {pose.fitness:5.3f} ({pose.generations} gen)  "
        f"age {pose.age_ms(now_ns):6.1f} ms"
    )


def format_json(pose: PoseMsg, now_ns: int) -> str:
    record = pose.to_dict()
    record["status_name"] = pose.status_name
    record["age_ms"] = round(pose.age_ms(now_ns), 3)
    return json.dumps(record)


def _version_warning() -> None:
    try:
        from importlib.metadata import version

        installed = version("iceoryx2")
    except Exception:  # noqa: BLE001
        return
    if installed != ICEORYX2_VERSION:
        print(
            f"warning: iceoryx2 {installed} installed, photopose uses {ICEORYX2_VERSION} "
            f"({INSTALL_HINT})",
            file=sys.stderr,
        )


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(
        description="Print the poses photopose publishes over iceoryx2."
    )
    parser.add_argument("--service", default=POSES_SERVICE, help=f"default {POSES_SERVICE}")
    parser.add_argument("--count", type=int, help="exit after N poses")
    parser.add_argument("--seconds", type=float, help="exit after S seconds")
    parser.add_argument("--object", help="only the poses of the object of this name")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    args = parser.parse_args(argv)
    if args.count is not None and args.count < 1:
        parser.error("--count must be at least 1")

    if iox2 is None:
        print(f"error: the Python package iceoryx2 is missing: {INSTALL_HINT}", file=sys.stderr)
        return 1
    _version_warning()
    fmt = format_json if args.json else format_line
    # Until the iceoryx2 node takes SIGTERM over (and after it is gone), SIGTERM ends the
    # client like Ctrl-C does, through the clean-up below.
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    received = 0
    terminated = False
    try:
        with PoseSubscriber(args.service) as sub:
            for pose in sub.poses(args.seconds):
                if args.object is not None and pose.object != args.object:
                    continue
                now_ns = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
                sys.stdout.write(fmt(pose, now_ns) + "\n")
                sys.stdout.flush()
                received += 1
                if args.count is not None and received >= args.count:
                    break
            terminated = sub.terminated
    except ClientError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        terminated = True
    except BrokenPipeError:  # piped into e.g. `head`, which has seen enough
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    if args.count is not None and received < args.count and not terminated:
        print(f"error: {received} of {args.count} poses in {args.seconds} s", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
