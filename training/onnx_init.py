"""Initial weights from an exported model: an ONNX file of :class:`training.model.CenterNetVehicle` back into torch.

The export folds each BatchNorm into its convolution (``do_constant_folding``), so the ONNX graph holds
one weight and one bias per conv. They go back into the conv, and the BatchNorm after it becomes an
identity (running mean 0, running variance 1 - eps, scale 1, shift = the folded bias): the torch net then
computes what the ONNX graph computes, and fine-tuning from it must keep BatchNorm frozen
(``training.train --freeze-bn``). Each ONNX Conv is matched to its module by the module path in its
output name (``/net/s4/s4.0/s4.0.0/Conv_output_0`` -> ``s4.0.0``).

    python -m training.onnx_init --onnx monorarp/models/centernet_vehicle.onnx --out data/shipped_init.pt
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from torch import nn

from training.model import CenterNetVehicle


def conv_weights(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Module path -> (weight, bias) of every Conv node of the exported graph."""
    import onnx
    from onnx import numpy_helper

    m = onnx.load(str(path))
    init = {t.name: numpy_helper.to_array(t) for t in m.graph.initializer}
    out = {}
    for n in m.graph.node:
        if n.op_type != "Conv":
            continue
        module = n.output[0].removeprefix("/net/").rsplit("/", 1)[0].rsplit("/", 1)[-1]
        out[module] = (init[n.input[1]], init[n.input[2]])
    return out


def net_from_onnx(path: Path) -> CenterNetVehicle:
    """A :class:`CenterNetVehicle` computing what the ONNX file computes (BatchNorm layers as identities)."""
    net = CenterNetVehicle()
    weights = conv_weights(path)
    modules = dict(net.named_modules())
    convs = [k for k, v in modules.items() if isinstance(v, nn.Conv2d)]
    if sorted(convs) != sorted(weights):
        raise ValueError(f"{path}: conv layers {sorted(weights)} do not match the net's {sorted(convs)}")
    with torch.no_grad():
        for name in convs:
            w, b = (torch.from_numpy(np.array(a, np.float32)) for a in weights[name])
            conv = modules[name]
            conv.weight.copy_(w)
            parent, _, idx = name.rpartition(".")
            bn = modules.get(f"{parent}.{int(idx) + 1}") if idx.isdigit() else None
            if isinstance(bn, nn.BatchNorm2d):
                bn.weight.fill_(1.0)
                bn.bias.copy_(b)
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
            else:
                conv.bias.copy_(b)
    return net


def fine_tune_shipped(d: Path, shards: list[Path], ckpt: Path, epochs: int, batch: int, lr: float, seed: int,
                      force: bool) -> Path:
    """Fine-tune the shipped model (its ONNX weights read back into ``d/shipped_init.pt``, BatchNorm frozen)
    on ``shards``; return ``ckpt`` (both steps skipped when their output exists, unless ``force``)."""
    from monorarp.detection.centernet import DEFAULT_MODEL
    from training import train

    init = d / "shipped_init.pt"
    if force or not init.exists():
        main(["--onnx", str(DEFAULT_MODEL), "--out", str(init)])
    if force or not ckpt.exists():
        train.main(["--data", *map(str, shards), "--out", str(ckpt), "--init", str(init), "--freeze-bn",
                    "--epochs", str(epochs), "--batch", str(batch), "--lr", str(lr), "--seed", str(seed)])
    return ckpt


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--onnx", type=Path, default=Path("monorarp/models/centernet_vehicle.onnx"))
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": net_from_onnx(a.onnx).state_dict(), "epoch": 0, "seed": None, "init": str(a.onnx)}, a.out)
    print(f"wrote {a.out} from {a.onnx}")


if __name__ == "__main__":
    main()
