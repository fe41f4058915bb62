"""The Dask cluster the points of a sweep, a gamma search and the robustness study run on: a local cluster
on the loopback address, or an existing scheduler (``tcp://``, or ``tls://`` with certificates), and the
command line's options for it."""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from ..cosim import CosimError

#: How many times a point whose worker died is run again on the local cluster (an existing scheduler
#: applies its own ``distributed.scheduler.allowed-failures``, Dask's default 3).
ALLOWED_FAILURES = 1


def dask_security(ca_file: str | None = None, cert: str | None = None, key: str | None = None) -> Any:
    """A ``distributed.security.Security`` for a ``tls://`` scheduler from PEM files (the CA that signed
    the scheduler's certificate, this client's certificate and its private key), requiring encryption;
    None when no file is given (Dask's configuration then applies).  CosimError if one is missing."""
    given = {"--tls-ca-file": ca_file, "--tls-cert": cert, "--tls-key": key}
    if not any(given.values()):
        return None
    for opt, f in given.items():
        if not f:
            raise CosimError(f"{opt}: missing (TLS needs --tls-ca-file, --tls-cert and --tls-key together)")
        if not Path(f).is_file():
            raise CosimError(f"{opt} {f}: file not found")
    from distributed.security import Security

    return Security(tls_ca_file=str(ca_file), tls_client_cert=str(cert), tls_client_key=str(key),
                    require_encryption=True)


def check_worker_count(workers: Any) -> None:
    """``--workers``: None (one local worker process per core) or a whole number >= 1; CosimError naming the
    option otherwise (0 is no worker, not a default)."""
    if workers is None:
        return
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise CosimError(f"--workers {workers}: must be a whole number >= 1 (the local worker processes; "
                         "leave it out for one per core)")


def cluster_options(args: Any) -> dict[str, Any]:
    """The Dask keyword arguments of ``sweep.run_sweep`` and ``gamma_search.gamma_search`` from the command line's options
    (``--workers``, ``--scheduler``, ``--dashboard``, ``--tls-ca-file``, ``--tls-cert``, ``--tls-key``),
    checked before anything runs."""
    check_worker_count(args.workers)
    sec = dask_security(getattr(args, "tls_ca_file", None), getattr(args, "tls_cert", None),
                        getattr(args, "tls_key", None))
    if sec is not None and not (args.scheduler or "").startswith("tls://"):
        raise CosimError("--tls-ca-file/--tls-cert/--tls-key: need --scheduler tls://HOST:PORT")
    return {"workers": args.workers, "scheduler": args.scheduler, "security": sec,
            "dashboard": bool(getattr(args, "dashboard", False))}


def cleartext_warning(address: str) -> str | None:
    """A one-line warning for a scheduler reached in clear text beyond this machine (``tcp://`` to an
    address other than the loopback), or None."""
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return None
    host = urlsplit(address).hostname or ""
    if host == "localhost" or host.startswith("127.") or host == "::1":
        return None
    return (f"wmr-cosim: warning: {address} is neither encrypted nor authenticated, and a Dask scheduler runs "
            "whatever it is sent: use tls:// unless every host that can reach it is trusted (docs/security.md)")


class Cluster:
    """A Dask client: a local cluster of ``workers`` processes (one thread each), or an existing
    scheduler at ``address`` (``tcp://`` or, with certificates, ``tls://``), whose workers must run this
    process's build of the project (shipment.py's ``check_workers``: refused in one line otherwise).

    The local cluster listens on the loopback address only (scheduler, workers and the scheduler's HTTP
    endpoint); its dashboard is off unless ``dashboard`` is true, and then it too listens on the loopback
    address only, and its address is printed on stderr.  ``security`` (a ``distributed.security.Security``,
    see :func:`dask_security`) gives the certificates for a ``tls://`` scheduler; without it Dask's own
    configuration (``distributed.comm.tls.*``) applies.  A Dask scheduler runs whatever code it is sent:
    see docs/security.md.
    """

    def __init__(self, workers: int | None = None, address: str | None = None, security: Any = None,
                 dashboard: bool = False) -> None:
        import logging

        from distributed import Client, LocalCluster

        check_worker_count(workers)
        t0 = time.perf_counter()
        self.cluster = None
        self.scratch: Path | None = None
        if address:
            warning = cleartext_warning(address)
            if warning:
                print(warning, file=sys.stderr)
            try:
                self.client = Client(address, timeout="10s", security=security)
            except Exception as exc:
                hint = ""
                if address.startswith("tls://") and security is None:
                    hint = "; a tls:// scheduler needs --tls-ca-file, --tls-cert and --tls-key (or Dask's configuration)"
                raise CosimError(f"--scheduler {address}: cannot connect ({' '.join(str(exc).split())}){hint}") from None
            from .shipment import check_workers
            try:
                check_workers(self.client, f"--scheduler {address}")
            except BaseException:
                self.client.close()
                raise
        else:
            # the scheduler's HTTP endpoint always runs: on the loopback address, at a free port, and it
            # serves the dashboard only when asked for (":0" would listen on every interface); the workers'
            # scratch folder is this cluster's own, removed on close (Dask leaves its default,
            # dask-scratch-space in the temporary folder, behind), and so is the workers' temporary folder
            # (TMPDIR): what a worker killed mid-run leaves there (a run's extracted FMUs) goes with it
            self.scratch = Path(tempfile.mkdtemp(prefix="wmr-dask-"))
            try:
                # a point whose worker dies is run once more, on another worker; a second death fails it
                sched: dict[str, Any] = {"local_directory": str(self.scratch), "allowed_failures": ALLOWED_FAILURES}
                if not dashboard:
                    sched["dashboard_address"] = "127.0.0.1:0"
                self.cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                                            processes=True, host="127.0.0.1",
                                            dashboard_address="127.0.0.1:0" if dashboard else None,
                                            scheduler_kwargs=sched, local_directory=str(self.scratch),
                                            env={"TMPDIR": str(self.scratch)}, silence_logs=logging.ERROR)
                self.client = Client(self.cluster)
            except BaseException:
                if self.cluster is not None:
                    self.cluster.close()
                shutil.rmtree(self.scratch, ignore_errors=True)
                raise
        self.dashboard = self.client.dashboard_link if dashboard else None
        if self.dashboard:
            print(f"dask dashboard: {self.dashboard}", file=sys.stderr)
        self.startup_s = time.perf_counter() - t0

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)

    def __enter__(self) -> "Cluster":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
