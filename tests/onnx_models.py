"""Tiny ONNX models for detector tests: fixed outputs whatever the input (not a test module)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper


def constant_model(path: Path, input_shape, outputs: dict[str, np.ndarray], input_name: str = "images") -> Path:
    """An ONNX model whose outputs are fixed tensors (plus 0 * mean(input), so the input is used)."""
    nodes = [helper.make_node("ReduceMean", [input_name], ["m"], keepdims=0),
             helper.make_node("Mul", ["m", "zero"], ["z"])]
    inits = [helper.make_tensor("zero", TensorProto.FLOAT, [], [0.0])]
    outs = []
    for name, arr in outputs.items():
        inits.append(helper.make_tensor(f"{name}_c", TensorProto.FLOAT, arr.shape, arr.astype(np.float32).ravel()))
        nodes.append(helper.make_node("Add", [f"{name}_c", "z"], [name]))
        outs.append(helper.make_tensor_value_info(name, TensorProto.FLOAT, list(arr.shape)))
    graph = helper.make_graph(nodes, "fixed", [helper.make_tensor_value_info(input_name, TensorProto.FLOAT, list(input_shape))],
                              outs, initializer=inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path
