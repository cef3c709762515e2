"""Export a trained checkpoint to ONNX (opset 17) and check torch/onnxruntime parity.

    python -m training.export --ckpt data/centernet.pt --out monorarp/models/centernet_vehicle.onnx
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
import torch

from training.data import Dataset
from training.model import CenterNetVehicle, ExportWrapper, of_size

INPUT_W, INPUT_H = 320, 192


def load_net(ckpt: Path) -> CenterNetVehicle:
    """The trained net of a checkpoint, of the size it records (``small`` when it records none)."""
    state = torch.load(ckpt, map_location="cpu")
    net = of_size(state.get("size", "small"))
    net.load_state_dict(state["model"])
    return net


def export(ckpt: Path, out: Path, check_data: Path | None = None, n_check: int = 8) -> float:
    """Write ``out``; return the max abs difference torch vs onnxruntime on a batch of images."""
    import onnx
    import onnxruntime as ort

    model = ExportWrapper(load_net(ckpt)).eval()
    dummy = torch.zeros(1, 3, INPUT_H, INPUT_W)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp.onnx")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, dummy, str(tmp), opset_version=17, input_names=["image"],
                          output_names=["heatmap", "ltrb"], do_constant_folding=True, dynamo=False)
    m = onnx.load(str(tmp))
    onnx.checker.check_model(m)
    m.producer_name = "monorarp-training"
    onnx.save(m, str(tmp))
    # parity on real images (or noise when no data is given)
    if check_data is not None:
        ds = Dataset.load(check_data)
        imgs = np.stack([ds.images[i] for i in range(min(n_check, len(ds.images)))])
        x = imgs[..., ::-1].transpose(0, 3, 1, 2).astype(np.float32) / 255.0
    else:
        x = np.random.default_rng(0).random((n_check, 3, INPUT_H, INPUT_W), dtype=np.float32)
    sess = ort.InferenceSession(str(tmp), providers=["CPUExecutionProvider"])
    worst = 0.0
    with torch.no_grad():
        for xi in x:
            t_hm, t_lt = model(torch.from_numpy(np.ascontiguousarray(xi[None])))
            o_hm, o_lt = sess.run(["heatmap", "ltrb"], {"image": np.ascontiguousarray(xi[None])})
            worst = max(worst, float(np.abs(t_hm.numpy() - o_hm).max()), float(np.abs(t_lt.numpy() - o_lt).max()))
    if worst > 1e-3:
        tmp.unlink()
        raise SystemExit(f"parity check failed: max |torch - onnxruntime| = {worst:.2e}")
    tmp.replace(out)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB), parity max abs diff {worst:.2e}")
    return worst


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--ckpt", type=Path, default=Path("data/centernet.pt"))
    ap.add_argument("--out", type=Path, default=Path("monorarp/models/centernet_vehicle.onnx"))
    ap.add_argument("--check-data", type=Path, default=None)
    a = ap.parse_args(argv)
    export(a.ckpt, a.out, a.check_data)


if __name__ == "__main__":
    main()
