"""Writes a tiny ONNX model with the SuperPoint interface the extractor
expects (input `image` [1, 1, H, W]; outputs `scores` [1, H, W] and `desc`
[1, 256, H/8, W/8]) for the C ABI fuzzer: loading and running it takes
about a millisecond, so the fuzzer spends its time in the ABI, not in the
network. Its weights are seeded random numbers; its keypoints mean nothing.

Usage: python make_tiny_model.py OUT.onnx
"""

import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper


def main(out_path: str) -> None:
    rng = np.random.default_rng(7)
    weights = rng.standard_normal((256, 1, 8, 8)).astype(np.float32)
    nodes = [
        # scores: the image's own brightness, through a sigmoid, [1, H, W].
        helper.make_node("Sigmoid", ["image"], ["probability"]),
        helper.make_node("Squeeze", ["probability", "axis1"], ["scores"]),
        # desc: one 8x8 stride-8 convolution, [1, 256, H/8, W/8].
        helper.make_node("Conv", ["image", "w"], ["desc"], kernel_shape=[8, 8], strides=[8, 8]),
    ]
    graph = helper.make_graph(
        nodes,
        "tiny_superpoint",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 1, "H", "W"])],
        [
            helper.make_tensor_value_info("scores", TensorProto.FLOAT, [1, "H", "W"]),
            helper.make_tensor_value_info("desc", TensorProto.FLOAT, [1, 256, "h", "w"]),
        ],
        initializer=[
            numpy_helper.from_array(weights, "w"),
            numpy_helper.from_array(np.array([1], dtype=np.int64), "axis1"),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, out_path)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: make_tiny_model.py OUT.onnx")
    main(sys.argv[1])
