"""Class 6 of issue 10: chatterlab's local dask cluster listens on loopback
only and opens no dashboard (checked by what actually listens), speaks TLS
with temporary credentials, and a remote scheduler is reached over TLS with
the user's certificates."""

from __future__ import annotations

import http.client
import ssl

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")

from chatterlab.cli._main import main  # noqa: E402
from chatterlab.sweep._backends import _local_cluster  # noqa: E402
from chatterlab.sweep._engine import sweep  # noqa: E402


def listeners() -> list[tuple[str, int]]:
    me = psutil.Process()
    pids = {me.pid} | {c.pid for c in me.children(recursive=True)}
    out = []
    for c in psutil.net_connections(kind="inet"):
        if c.status == psutil.CONN_LISTEN and c.pid in pids:
            out.append((c.laddr.ip, c.laddr.port))
    return sorted(out)


def http_status(ip: str, port: int, path: str) -> int | str:
    conn = http.client.HTTPConnection(ip, port, timeout=2)
    try:
        conn.request("GET", path)
        return conn.getresponse().status
    except (OSError, http.client.HTTPException, ssl.SSLError) as exc:  # a TLS port hangs up on HTTP
        return type(exc).__name__
    finally:
        conn.close()


def _cube(x: float) -> dict[str, float]:
    return {"y": x**3}


@pytest.mark.slow
def test_local_cluster_listens_on_loopback_only_without_dashboard():
    before = set(listeners())
    cluster, client = _local_cluster(2)
    try:
        opened = [a for a in listeners() if a not in before]
        assert opened, "the cluster listens somewhere"
        assert all(ip in ("127.0.0.1", "::1") for ip, _ in opened), opened
        assert all(port != 8787 for _, port in opened), opened
        for ip, port in opened:  # no page answers: no dashboard, no info, no metrics
            for path in ("/status", "/info/main/workers.html", "/metrics", "/json/index.html"):
                assert http_status(ip, port, path) != 200, (port, path)
        # the scheduler refuses a client without the cluster's credentials
        address = cluster.scheduler_address
        assert address.startswith("tls://127.0.0.1:")
        with pytest.raises((OSError, TimeoutError)):
            distributed.Client(address.replace("tls://", "tcp://"), timeout=2, set_as_default=False)
    finally:
        client.close()
        cluster.close()


@pytest.mark.slow
def test_dask_backend_gives_the_serial_result():
    g = {"x": np.linspace(0.0, 1.0, 7)}
    a = sweep(_cube, g, outputs={"y": ""}, backend="dask", jobs=2, progress=False)
    b = sweep(_cube, g, outputs={"y": ""}, backend="serial", progress=False)
    assert np.array_equal(a["y"], b["y"])


@pytest.mark.slow
def test_remote_scheduler_over_tls_with_the_users_certificates(tmp_path, capsys):
    from distributed import LocalCluster
    from distributed.security import Security

    sec = Security.temporary()  # stands for the site's CA and the user's certificate
    pem = {}
    for name, text in (("ca", sec.tls_ca_file), ("cert", sec.tls_client_cert), ("key", sec.tls_client_key)):
        pem[name] = tmp_path / f"{name}.pem"
        pem[name].write_text(text)
    remote = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, host="127.0.0.1", protocol="tls",
        security=sec, dashboard_address=None,
    )  # fmt: skip
    try:
        address = remote.scheduler_address
        user = Security(
            tls_ca_file=str(pem["ca"]), tls_client_cert=str(pem["cert"]), tls_client_key=str(pem["key"]),
            require_encryption=True,
        )  # fmt: skip
        r = sweep(_cube, {"x": [2.0]}, outputs={"y": ""}, backend="dask", scheduler=address, security=user, progress=False)  # fmt: skip
        assert r.ok and r["y"][0] == 8.0
        model = tmp_path / "m.toml"
        from conftest import turning_text

        model.write_text(turning_text())
        argv = ["sweep", str(model), "--quantity", "b-lim", "--grid", "speed=3000", "--backend", "dask",
                "--scheduler", address, "--quiet"]  # fmt: skip
        tls = ["--tls-ca-file", str(pem["ca"]), "--tls-cert", str(pem["cert"]), "--tls-key", str(pem["key"])]
        assert main(argv + tls) == 0, capsys.readouterr().err
    finally:
        remote.close()


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--scheduler", "tls://127.0.0.1:1"], ["tls:// scheduler needs", "--tls-ca-file"]),
        (["--scheduler", "tcp://127.0.0.1:1", "--tls-cert", "c.pem"], ["--tls-cert", "tls://"]),
        (["--scheduler", "tls://127.0.0.1:1", "--tls-ca-file", "x", "--tls-cert", "y", "--tls-key", "z"], ["no such file"]),
    ],
)  # fmt: skip
def test_tls_options_are_checked(capsys, tmp_path, extra, words):
    from conftest import turning_text

    model = tmp_path / "m.toml"
    model.write_text(turning_text())
    code = main(
        ["sweep", str(model), "--quantity", "b-lim", "--grid", "speed=3000", "--backend", "dask", *extra]
    )
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, err
