"""The net's named sizes (training.model.SIZES): parameter counts within the 10 MB model budget, a checkpoint
that records its size loads back as that size, and an unknown size is refused."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from training import export  # noqa: E402
from training.model import SIZES, n_params, of_size  # noqa: E402


def test_sizes_fit_the_model_budget_and_large_is_larger():
    counts = {s: n_params(of_size(s)) for s in SIZES}
    assert counts["small"] == 401_037                         # the shipped models' count (model cards)
    assert counts["small"] < counts["large"] and 4 * counts["large"] <= 10_000_000   # float32 bytes


@pytest.mark.parametrize("size", sorted(SIZES))
def test_a_checkpoint_loads_back_as_the_size_it_records(size, tmp_path):
    net = of_size(size).eval()
    ckpt = tmp_path / "n.pt"
    torch.save({"model": net.state_dict(), "size": size}, ckpt)
    back = export.load_net(ckpt).eval()
    x = torch.rand(1, 3, 192, 320)
    with torch.no_grad():
        assert all(torch.equal(a, b) for a, b in zip(net(x), back(x)))


def test_a_checkpoint_without_a_size_is_small_and_an_unknown_size_is_refused(tmp_path):
    ckpt = tmp_path / "old.pt"
    torch.save({"model": of_size("small").state_dict()}, ckpt)     # written before sizes existed
    assert n_params(export.load_net(ckpt)) == 401_037
    with pytest.raises(ValueError, match="unknown net size 'huge'"):
        of_size("huge")
