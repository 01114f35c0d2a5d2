"""Builds the tiny test models of deepcontact-onnx (run once; outputs are committed).

    python warmstart/onnx/tests/data/make_test_models.py

tiny.onnx: grids [1,6,61,61] -> Conv 3x3 (6->4) -> Relu -> AveragePool 2 (ceil) -> Resize to 61
(linear, align_corners) -> Conv 1x1 (4->2) + skip Conv 1x1 (6->2) -> impulses [1,2,61,61].
Small, but it exercises the ops of the shipped models. wrong_output.onnx writes 3 channels.
"""

import json
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

HERE = Path(__file__).resolve().parent
rng = np.random.default_rng(7)


def init(name, array):
    return numpy_helper.from_array(np.asarray(array, dtype=np.float32), name)


def tiny(out_channels=2):
    w1 = rng.normal(0, 0.2, (4, 6, 3, 3))
    w2 = rng.normal(0, 0.3, (out_channels, 4, 1, 1))
    ws = rng.normal(0, 0.3, (out_channels, 6, 1, 1))
    nodes = [
        helper.make_node("Conv", ["grids", "w1", "b1"], ["c1"], kernel_shape=[3, 3], pads=[1, 1, 1, 1]),
        helper.make_node("Relu", ["c1"], ["r1"]),
        helper.make_node("AveragePool", ["r1"], ["p1"], kernel_shape=[2, 2], strides=[2, 2], ceil_mode=1),
        helper.make_node("Resize", ["p1", "", "", "sizes"], ["u1"], mode="linear",
                         coordinate_transformation_mode="align_corners"),
        helper.make_node("Conv", ["u1", "w2", "b2"], ["h1"], kernel_shape=[1, 1]),
        helper.make_node("Conv", ["grids", "ws"], ["h2"], kernel_shape=[1, 1]),
        helper.make_node("Add", ["h1", "h2"], ["impulses"]),
    ]
    graph = helper.make_graph(
        nodes, "tiny",
        [helper.make_tensor_value_info("grids", TensorProto.FLOAT, [1, 6, 61, 61])],
        [helper.make_tensor_value_info("impulses", TensorProto.FLOAT, [1, out_channels, 61, 61])],
        [init("w1", w1), init("b1", rng.normal(0, 0.1, 4)), init("w2", w2), init("b2", np.full(out_channels, 0.05)),
         init("ws", ws), numpy_helper.from_array(np.array([1, 4, 61, 61], dtype=np.int64), "sizes")],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="deepcontact-tests")
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model


layout = {
    "version": 1,
    "grid": {"origin": [0.0, 0.0], "spacing": 0.25, "nx": 61, "ny": 61},
    "order": "chw",
    "kernel": {"kind": "poly6"},
    "h": 0.5,
    "search": "exact",
    "g2p": "sph",
    "input_channels": ["mass", "vx", "vy", "omega", "nx", "ny"],
    "output_channels": ["normal_impulse", "tangent_impulse"],
    "wall_mass": 100.0,
    "wall_band": 0.125,
}


def card(name, out_channels=("normal_impulse", "tangent_impulse"), in_channels=None, in_shape=(1, 6, 61, 61)):
    return {
        "format": "deepcontact-model-card", "format_version": 1, "name": name,
        "architecture": "test model: conv 3x3 + relu + avg-pool + resize + 1x1 convs",
        "parameters": 0, "grid_layout": layout,
        "input": {"name": "grids", "shape": list(in_shape), "channels": list(in_channels or layout["input_channels"])},
        "output": {"name": "impulses", "shape": [1, len(out_channels), 61, 61], "channels": list(out_channels)},
        "training": {"note": "random weights, for tests only"},
    }


def write(name, obj):
    (HERE / name).write_text(json.dumps(obj, indent=2) + "\n")


onnx.save(tiny(), str(HERE / "tiny.onnx"))
write("tiny.json", card("tiny"))
swapped = list(layout["input_channels"])
swapped[1], swapped[2] = swapped[2], swapped[1]
write("tiny_swapped_channels.json", card("tiny", in_channels=swapped))
write("tiny_wrong_shape.json", card("tiny", in_shape=(1, 6, 64, 64)))
onnx.save(tiny(out_channels=3), str(HERE / "wrong_output.onnx"))
# Its card is right about the grid; the model itself writes 3 channels.
write("wrong_output.json", card("wrong_output"))
print("written to", HERE)


def reference_input():
    """The deterministic input the Rust tests rebuild: x[c, j, i] = sin(0.1 (c + 1) i) cos(0.07 j) + 0.1 c."""
    c, j, i = np.meshgrid(np.arange(6), np.arange(61), np.arange(61), indexing="ij")
    return (np.sin(0.1 * (c + 1) * i) * np.cos(0.07 * j) + 0.1 * c).astype(np.float32)[None]


try:
    import onnxruntime as ort

    sess = ort.InferenceSession(str(HERE / "tiny.onnx"), providers=["CPUExecutionProvider"])
    out = sess.run(None, {"grids": reference_input()})[0].astype("<f4")
    (HERE / "tiny_reference.bin").write_bytes(out.tobytes())
    print("reference output (onnxruntime", ort.__version__, ") written")
except ImportError:
    print("onnxruntime not installed: tiny_reference.bin not written")
