"""`monorarp sweep --executor ray`: same metrics as the local executor; unreachable addresses fail fast.

Needs the optional extra (`pip install ".[ray]"`); skipped otherwise.
"""

from __future__ import annotations

import json
import socket

import pytest
import yaml

pytest.importorskip("ray", reason="Ray is not installed (optional extra: pip install '.[ray]')")

from harness.check.metrics import deterministic_metrics  # noqa: E402
from monorarp.app.cli import main  # noqa: E402
from synthetic import tiny_scenario, vehicle  # noqa: E402

SCENARIO = tiny_scenario("tiny", 0, [vehicle("lead", 0, 14, 20), vehicle("left", -1, 22, 26)])
SPEC = {"name": "ray_t", "scenarios": ["tiny.yaml"], "seeds": [1, 2], "frames": 5,
        "variants": [{"name": "pf", "detector": "oracle", "detector_kwargs": {"jitter_px": 1.0}, "tracker": "particle"}]}


@pytest.fixture()
def spec(tmp_path):
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(SCENARIO))
    p = tmp_path / "spec.yaml"
    p.write_text(yaml.safe_dump(SPEC))
    return p


def metrics(d):
    return {r["id"]: (r["status"], deterministic_metrics(r["metrics"]))
            for r in json.loads((d / "summary.json").read_text())["runs"]}


def test_ray_matches_local_executor(spec, tmp_path):
    assert main(["sweep", str(spec), "--out", str(tmp_path / "local"), "--no-progress"]) == 0
    assert main(["sweep", str(spec), "--out", str(tmp_path / "ray"), "--executor", "ray", "--workers", "2",
                 "--no-progress"]) == 0
    local, ray_ = metrics(tmp_path / "local"), metrics(tmp_path / "ray")
    assert len(local) == 2 and all(s == "ok" for s, _ in local.values())
    assert local == ray_
    # the driver wrote the workers' files: same set of files per run
    for rid in local:
        names = lambda d: sorted(p.name for p in (d / "runs" / rid).iterdir())  # noqa: E731
        assert names(tmp_path / "local") == names(tmp_path / "ray")


def test_unreachable_address_fails_fast(spec, tmp_path, capsys):
    with socket.socket() as s:          # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--executor", "ray", "--address", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err
    assert f"127.0.0.1:{port}" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_non_ray_server_is_refused(spec, tmp_path, capsys):
    """Something listens (a plain TCP server that never speaks gRPC): refused by the probe, not ray.init."""
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    port = srv.getsockname()[1]
    stop = threading.Event()

    def serve():
        srv.settimeout(0.2)
        conns = []
        while not stop.is_set():
            try:
                conns.append(srv.accept()[0])
            except OSError:
                continue
        for c in conns:
            c.close()

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    try:
        from harness.sweep.executors import ExecutorError, probe

        with pytest.raises(ExecutorError, match=f"127.0.0.1:{port}"):
            probe(f"127.0.0.1:{port}", timeout_s=1.0)
    finally:
        stop.set()
        th.join()
        srv.close()
