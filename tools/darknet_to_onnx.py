#!/usr/bin/env python3
"""Converts a Darknet YOLOv3(-tiny) network (.cfg + .weights) into an ONNX detector.

Usage: darknet_to_onnx.py NET.cfg NET.weights OUT.onnx

The graph photopose's detector reads:

- input ``images``: float32 ``[1, 3, H, W]`` (H, W from the cfg's [net], 416 × 416 for
  YOLOv3-tiny), RGB in 0..1, letterboxed;
- output ``output0``: float32 ``[1, N, 5 + C]``, the YOLOv5 export layout: one row per
  anchor box of every [yolo] head (N = Σ grid_w × grid_h × anchors; 2535 for YOLOv3-tiny
  at 416), with ``cx, cy, w, h`` in input pixels, the objectness and the C class
  probabilities (all after the sigmoid, as Darknet computes them). The score of a class
  is objectness × class probability.

Batch normalisation is folded into the convolutions (Darknet divides by
``sqrt(var) + 1e-6``); the YOLO box decoding (``(grid + sigmoid(t)) · stride`` and
``exp(t) · anchor``, ``scale_x_y`` honoured) is part of the graph. Supported layers:
convolutional (leaky or linear), maxpool, upsample, route, shortcut, yolo. Needs numpy
and the ``onnx`` package only.
"""

import sys

try:
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper
except ImportError as e:
    sys.exit(f"darknet_to_onnx: {e} (tools/setup-detect installs numpy and onnx into .detect/python)")


def parse_cfg(path):
    """The cfg as a list of (section, {key: value}) in file order."""
    sections = []
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            if line.startswith("["):
                if not line.endswith("]"):
                    raise ValueError(f"{path}: malformed section header {line!r}")
                sections.append((line[1:-1].strip(), {}))
            else:
                if not sections or "=" not in line:
                    raise ValueError(f"{path}: unexpected line {line!r}")
                key, value = line.split("=", 1)
                sections[-1][1][key.strip()] = value.strip()
    if not sections or sections[0][0] not in ("net", "network"):
        raise ValueError(f"{path}: the first section must be [net]")
    return sections


def ints(text):
    return [int(v) for v in text.split(",") if v.strip()]


class Weights:
    """Reads the .weights file: a header, then float32 parameters layer by layer."""

    def __init__(self, path):
        with open(path, "rb") as f:
            data = f.read()
        if len(data) < 20:
            raise ValueError(f"{path}: {len(data)} bytes is too short for a Darknet weights file")
        major, minor, _revision = np.frombuffer(data, dtype="<i4", count=3)
        seen_bytes = 8 if major * 10 + minor >= 2 else 4
        offset = 12 + seen_bytes
        self.path = path
        self.values = np.frombuffer(data, dtype="<f4", offset=offset)
        self.pos = 0

    def take(self, n):
        if self.pos + n > self.values.size:
            raise ValueError(f"{self.path}: too short for the cfg (needs more than {self.values.size} floats)")
        out = self.values[self.pos : self.pos + n].astype(np.float32)
        self.pos += n
        return out

    def check_consumed(self):
        if self.pos != self.values.size:
            raise ValueError(f"{self.path}: {self.values.size - self.pos} floats left over: weights do not match the cfg")


class Graph:
    def __init__(self):
        self.nodes = []
        self.inits = []
        self.count = 0

    def name(self, stem):
        self.count += 1
        return f"{stem}_{self.count}"

    def const(self, stem, array):
        n = self.name(stem)
        self.inits.append(numpy_helper.from_array(np.asarray(array), n))
        return n

    def op(self, op_type, inputs, stem=None, **attrs):
        out = self.name(stem or op_type.lower())
        self.nodes.append(helper.make_node(op_type, inputs, [out], **attrs))
        return out


def convert(cfg_path, weights_path, out_path):
    sections = parse_cfg(cfg_path)
    net = sections[0][1]
    height, width = int(net.get("height", 416)), int(net.get("width", 416))
    channels = int(net.get("channels", 3))
    weights = Weights(weights_path)
    g = Graph()
    x = "images"
    shapes = []  # (channels, h, w) of every layer's output
    outputs = []  # tensor name of every layer's output
    heads = []  # decoded [1, n, 5 + C] tensors
    c, h, w = channels, height, width
    for index, (kind, opts) in enumerate(sections[1:]):
        if kind == "convolutional":
            filters, size = int(opts["filters"]), int(opts["size"])
            stride = int(opts.get("stride", 1))
            pad = size // 2 if int(opts.get("pad", 0)) else int(opts.get("padding", 0))
            groups = int(opts.get("groups", 1))
            bn = int(opts.get("batch_normalize", 0))
            biases = weights.take(filters)
            if bn:
                scales = weights.take(filters)
                mean = weights.take(filters)
                var = weights.take(filters)
            kernel = weights.take(filters * (c // groups) * size * size).reshape(filters, c // groups, size, size)
            if bn:
                factor = scales / (np.sqrt(var) + 1e-6)
                kernel = kernel * factor[:, None, None, None]
                biases = biases - mean * factor
            x = g.op(
                "Conv",
                [x, g.const("w", kernel.astype(np.float32)), g.const("b", biases.astype(np.float32))],
                kernel_shape=[size, size],
                strides=[stride, stride],
                pads=[pad, pad, pad, pad],
                group=groups,
            )
            activation = opts.get("activation", "logistic")
            if activation == "leaky":
                x = g.op("LeakyRelu", [x], alpha=0.1)
            elif activation == "logistic":
                x = g.op("Sigmoid", [x])
            elif activation != "linear":
                raise ValueError(f"{cfg_path}: layer {index}: activation {activation!r} is not supported")
            c = filters
            h = (h + 2 * pad - size) // stride + 1
            w = (w + 2 * pad - size) // stride + 1
        elif kind == "maxpool":
            size = int(opts.get("size", 2))
            stride = int(opts.get("stride", size))
            padding = int(opts.get("padding", size - 1))
            # Darknet starts the windows at -padding/2 (C division) and its output has
            # (h + padding - size)/stride + 1 rows; pad the end as far as they reach.
            begin = padding // 2
            oh = (h + padding - size) // stride + 1
            ow = (w + padding - size) // stride + 1
            end_h = max(0, (oh - 1) * stride + size - h - begin)
            end_w = max(0, (ow - 1) * stride + size - w - begin)
            x = g.op(
                "MaxPool",
                [x],
                kernel_shape=[size, size],
                strides=[stride, stride],
                pads=[begin, begin, end_h, end_w],
            )
            h, w = oh, ow
        elif kind == "upsample":
            stride = int(opts.get("stride", 2))
            scales = g.const("scales", np.array([1, 1, stride, stride], dtype=np.float32))
            x = g.op(
                "Resize",
                [x, "", scales],
                mode="nearest",
                coordinate_transformation_mode="asymmetric",
                nearest_mode="floor",
            )
            h, w = h * stride, w * stride
        elif kind == "route":
            if int(opts.get("groups", 1)) != 1:
                raise ValueError(f"{cfg_path}: layer {index}: [route] groups is not supported")
            layers = [l if l >= 0 else index + l for l in ints(opts["layers"])]
            if len(layers) == 1:
                x = outputs[layers[0]]
                c, h, w = shapes[layers[0]]
            else:
                x = g.op("Concat", [outputs[l] for l in layers], axis=1)
                c = sum(shapes[l][0] for l in layers)
                _, h, w = shapes[layers[0]]
        elif kind == "shortcut":
            if opts.get("activation", "linear") != "linear":
                raise ValueError(f"{cfg_path}: layer {index}: [shortcut] activation is not supported")
            src = int(opts["from"])
            src = src if src >= 0 else index + src
            x = g.op("Add", [x, outputs[src]])
        elif kind == "yolo":
            heads.append(yolo_head(g, x, opts, (c, h, w), (height, width), cfg_path, index))
        else:
            raise ValueError(f"{cfg_path}: layer {index}: [{kind}] is not supported")
        outputs.append(x)
        shapes.append((c, h, w))
    weights.check_consumed()
    if not heads:
        raise ValueError(f"{cfg_path}: no [yolo] layer")
    out = g.op("Concat", heads, axis=1) if len(heads) > 1 else heads[0]
    g.nodes.append(helper.make_node("Identity", [out], ["output0"]))
    classes = yolo_classes(sections)
    n = sum(
        shapes[i][1] * shapes[i][2] * len(ints(o["mask"]))
        for i, (k, o) in enumerate(sections[1:])
        if k == "yolo"
    )
    graph = helper.make_graph(
        g.nodes,
        "darknet-yolo",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, channels, height, width])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, n, 5 + classes])],
        g.inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)], producer_name="photopose")
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, out_path)
    return n, classes


def yolo_classes(sections):
    return int(next(o for k, o in sections if k == "yolo").get("classes", 80))


def yolo_head(g, x, opts, shape, net_size, cfg_path, index):
    """Decodes one [yolo] layer's raw map into [1, gh·gw·A, 5 + C] rows."""
    c, gh, gw = shape
    classes = int(opts.get("classes", 80))
    mask = ints(opts["mask"])
    anchors = np.array(ints(opts["anchors"]), dtype=np.float32).reshape(-1, 2)[mask]
    a = len(mask)
    if c != a * (5 + classes):
        raise ValueError(f"{cfg_path}: layer {index}: {c} channels, expected {a} × (5 + {classes})")
    scale_xy = float(opts.get("scale_x_y", 1.0))
    height, width = net_size
    stride = np.array([width / gw, height / gh], dtype=np.float32)
    # [1, A·(5+C), gh, gw] → [1, A, 5+C, gh, gw] → [1, A, gh, gw, 5+C]
    t = g.op("Reshape", [x, g.const("shape", np.array([1, a, 5 + classes, gh, gw], dtype=np.int64))])
    t = g.op("Transpose", [t], perm=[0, 1, 3, 4, 2])

    def part(start, end):
        return g.op(
            "Slice",
            [
                t,
                g.const("starts", np.array([start], dtype=np.int64)),
                g.const("ends", np.array([end], dtype=np.int64)),
                g.const("axes", np.array([4], dtype=np.int64)),
            ],
        )

    xy = g.op("Sigmoid", [part(0, 2)])
    if scale_xy != 1.0:
        xy = g.op("Mul", [xy, g.const("sxy", np.float32(scale_xy))])
        xy = g.op("Sub", [xy, g.const("sxy0", np.float32(0.5 * (scale_xy - 1.0)))])
    gx, gy = np.meshgrid(np.arange(gw, dtype=np.float32), np.arange(gh, dtype=np.float32))
    grid = np.stack([gx, gy], axis=-1).reshape(1, 1, gh, gw, 2)
    xy = g.op("Add", [xy, g.const("grid", grid)])
    xy = g.op("Mul", [xy, g.const("stride", stride.reshape(1, 1, 1, 1, 2))])
    wh = g.op("Exp", [part(2, 4)])
    wh = g.op("Mul", [wh, g.const("anchors", anchors.reshape(1, a, 1, 1, 2))])
    rest = g.op("Sigmoid", [part(4, 5 + classes)])
    rows = g.op("Concat", [xy, wh, rest], axis=4)
    return g.op("Reshape", [rows, g.const("shape", np.array([1, a * gh * gw, 5 + classes], dtype=np.int64))])


def main(argv):
    if len(argv) != 4:
        print("usage: darknet_to_onnx.py NET.cfg NET.weights OUT.onnx", file=sys.stderr)
        return 2
    try:
        n, classes = convert(argv[1], argv[2], argv[3])
    except (OSError, ValueError, KeyError, onnx.checker.ValidationError) as e:
        print(f"darknet_to_onnx: {e}", file=sys.stderr)
        return 1
    print(f"wrote {argv[3]}: output0 [1, {n}, {5 + classes}]")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
