"""What the points of a study read, sent with the work to whichever worker runs them.

A point on a Dask worker reads no file of the driver's, so a study runs on a cluster that shares no file
system with it (Kubernetes, an HPC queue, a cloud).  The driver reads the study's scenario files (each
base with its chain of bases merged: one document per base, :func:`pack`) and every FMU and input table
they name, and each model name's FMU; it sends the files by content (SHA-256) to every worker once, in a
Dask worker plugin (:class:`FileShipping`: a worker that joins later, or replaces one that died, gets them
as it starts), and the documents with every point.  Each worker writes the files into its own cache, in
its local directory (``<local_directory>/wmr-cosim-files/<sha256>/<file name>``), checking each file's
hash; a point's runs read them there (:meth:`Shipment.protocol`).  A file already in a worker's cache is
not written again: a second study with the same FMUs costs that worker nothing but the transfer.

Why a plugin of our own rather than ``Client.upload_file``: that one stores a file under its base name in
the worker's folder (two ``model.fmu`` of two folders would overwrite each other) and is meant for Python
modules; ours addresses files by content, checks them, and sends all of a study's in one message.

The project itself must be installed on the workers: :func:`build` names the version a process runs
(the package's version, a digest of its sources, FMPy's version), which the driver compares with every
worker's before a study starts (:func:`check_workers`) and which every point checks again on its worker.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..cosim import CosimError, LimitOverrides, Protocol, is_path, read_document

try:
    from distributed.diagnostics.plugin import WorkerPlugin
except ImportError:    # (studies need the [sweep] extra; the rest of this module does not)
    WorkerPlugin = object  # type: ignore[misc,assignment]

#: The folder of shipped files in a worker's local directory.
CACHE = "wmr-cosim-files"
#: What each worker's plugin wrote, by plugin name: (bytes written, bytes already cached, seconds).
_RECEIVED: dict[str, tuple[int, int, float]] = {}


@functools.lru_cache(maxsize=1)
def build() -> str:
    """What this process runs: wmr-cosim's version and a digest of its sources (its Python files and the
    FMUs' sources), and FMPy's version.  Two processes whose builds differ may compute different results."""
    import fmpy

    from .. import version

    root = Path(__file__).resolve().parents[1]   # the package (this module is in its studies/)
    h = hashlib.sha256()
    for f in sorted(p for p in root.rglob("*") if p.suffix in (".py", ".c", ".h") and "__pycache__" not in p.parts):
        h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return f"wmr-cosim {version()} (sources {h.hexdigest()[:12]}), FMPy {fmpy.__version__}"


def check_workers(client: Any, where: str) -> None:
    """CosimError naming the first worker of ``client``'s cluster that runs another build than this
    process (:func:`build`); ``where`` names the cluster in the message (``--scheduler tcp://...``)."""
    ours = build()
    for worker, theirs in sorted(client.run(build).items()):
        if theirs != ours:
            raise CosimError(f"{where}: worker {worker} runs {theirs}, this driver {ours}: install the driver's "
                             "version on every worker")


@dataclass(frozen=True)
class ShippedFile:
    """A file a study reads: its SHA-256 (hex), its base name, its size [bytes]."""

    sha256: str
    name: str
    size: int


@dataclass(frozen=True)
class Shipment:
    """What a study's points read, as the driver read it: ``documents`` {base file as the study names it:
    its document, bases merged, FMU and input paths the driver's}, ``files`` {the driver's path as the
    documents name it: the file}, ``models`` {model name: the driver's path of its FMU}; ``build`` the
    driver's :func:`build`.  Small: it travels with every point (the files' bytes travel once per worker,
    in the plugin)."""

    documents: dict[str, dict[str, Any]]
    files: dict[str, ShippedFile]
    models: dict[str, str]
    build: str
    plugin: str = field(default="")

    def names(self) -> dict[str, list[str]]:
        """The base names of the files by SHA-256 (one content may come under several names)."""
        names: dict[str, list[str]] = {}
        for f in self.files.values():
            if f.name not in names.setdefault(f.sha256, []):
                names[f.sha256].append(f.name)
        return names

    def cached(self, path: str, folder: Path) -> Path:
        """Where the driver's file ``path`` lies, whole, in the worker cache ``folder``; CosimError if it is
        not there."""
        f = self.files[path]
        p = folder / f.sha256 / f.name
        if not p.is_file() or p.stat().st_size != f.size:
            raise CosimError(f"{path}: not shipped to this worker ({CACHE}/{f.sha256[:12]}... missing)")
        return p

    def protocol(self, base: str, limits: LimitOverrides | None, folder: Path | None = None
                 ) -> tuple[Protocol, Callable[[str], str]]:
        """The protocol of ``base`` on this worker, its FMUs and inputs read from the cache (``folder``:
        this worker's, by default), and what turns the cache's paths in a message back into the driver's
        (a point's reason is the same on every worker).  CosimError if this worker runs another build."""
        if self.build != build():
            raise CosimError(f"this worker runs {build()}, the driver {self.build}: install the driver's version "
                             "on every worker")
        folder = folder if folder is not None else worker_cache()
        doc = copy.deepcopy(self.documents[base])
        back: dict[str, str] = {}

        def local(path: str) -> str:
            p = str(self.cached(path, folder))
            back[p] = path
            return p

        for inst in (doc.get("instances") or {}).values():
            if isinstance(inst, dict) and isinstance(inst.get("fmu"), str) and inst["fmu"] in self.files:
                inst["fmu"] = local(inst["fmu"])
        inputs = doc.get("inputs")
        if isinstance(inputs, dict) and inputs.get("file") in self.files:
            inputs["file"] = local(inputs["file"])
        models = {name: Path(local(path)) for name, path in self.models.items()}

        def unlocalise(text: str) -> str:
            for mine, theirs in back.items():
                text = text.replace(mine, theirs)
            return text

        return Protocol.from_document(base, doc, models.get, limits), unlocalise


def pack(bases: list[str], models: Callable[[str], Path | None], shipped: Path | None = None
         ) -> tuple[Shipment, dict[str, bytes]]:
    """Read the study's bases (scenario files; ``shipped``: the folder of scenario files a ``base`` may
    name) and what they name: the shipment and the files' bytes by SHA-256.  ``models``: model name -> FMU
    path (None: not a model name), for the instances that name a model rather than a file; only those the
    documents name are resolved and sent.  CosimError naming the file that cannot be read."""
    documents: dict[str, dict[str, Any]] = {}
    files: dict[str, ShippedFile] = {}
    blobs: dict[str, bytes] = {}
    used: dict[str, str] = {}

    def add(path: str, what: str) -> None:
        if path in files:
            return
        try:
            data = Path(path).read_bytes()
        except OSError as exc:
            raise CosimError(f"{what}: {path}: cannot be read ({exc.strerror or exc})") from None
        digest = hashlib.sha256(data).hexdigest()
        files[path] = ShippedFile(digest, Path(path).name, len(data))
        blobs[digest] = data

    for base in dict.fromkeys(bases):
        doc = read_document(Path(base), shipped=shipped)
        documents[base] = doc
        for name, inst in (doc.get("instances") or {}).items():
            fmu = inst.get("fmu") if isinstance(inst, dict) else None
            if not isinstance(fmu, str):
                continue
            if is_path(fmu):
                add(fmu, f"{base}: instances.{name}.fmu")
                continue
            if fmu not in used and (found := models(fmu)) is not None:
                used[fmu] = str(Path(found).resolve())
            if fmu in used:
                add(used[fmu], f"{base}: instances.{name}.fmu ({fmu})")
        inputs = doc.get("inputs")
        if isinstance(inputs, dict) and isinstance(inputs.get("file"), str):
            add(inputs["file"], f"{base}: inputs.file")
    return Shipment(documents, files, used, build()), blobs


def worker_cache() -> Path:
    """The cache of shipped files of the Dask worker this runs in."""
    from distributed import get_worker

    return Path(get_worker().local_directory) / CACHE


def store(folder: Path, blobs: dict[str, bytes], names: dict[str, list[str]]) -> tuple[int, int]:
    """Write each file (``blobs`` by SHA-256, ``names`` its base names) into ``folder/<sha256>/<name>``
    unless there already, checking its hash; returns (bytes written, bytes found already cached)."""
    written = cached = 0
    for digest, data in blobs.items():
        if hashlib.sha256(data).hexdigest() != digest:
            raise CosimError(f"{CACHE}: a file arrived damaged (SHA-256 {digest[:12]}... does not match)")
        for name in names[digest]:
            dest = folder / digest / name
            if dest.is_file() and dest.stat().st_size == len(data):
                cached += len(data)
                continue
            dest.parent.mkdir(parents=True, exist_ok=True)
            part = dest.with_name(f".{name}.{os.getpid()}.part")   # whole, then renamed: a file there is complete
            part.write_bytes(data)
            os.replace(part, dest)
            written += len(data)
    return written, cached


class FileShipping(WorkerPlugin):
    """The Dask worker plugin that carries a study's files to every worker, now and as workers join
    (:func:`ship`); it writes them into the worker's cache as the worker takes it (:func:`store`)."""

    def __init__(self, name: str, blobs: dict[str, bytes], names: dict[str, list[str]]) -> None:
        self.name = name
        self.blobs = blobs
        self.names = names

    def setup(self, worker: Any) -> None:
        t0 = time.perf_counter()
        written, cached = store(Path(worker.local_directory) / CACHE, self.blobs, self.names)
        _RECEIVED[self.name] = (written, cached, time.perf_counter() - t0)

    def teardown(self, worker: Any) -> None:
        _RECEIVED.pop(self.name, None)   # (the files stay: a later study may ship the same ones)


def _received(name: str) -> tuple[int, int, float] | None:
    return _RECEIVED.get(name)


@dataclass(frozen=True)
class ShippingCost:
    """What sending a study's files cost: ``bytes`` sent to each worker, ``seconds`` for all workers to
    hold them (the driver's wall time), and per worker (bytes written, bytes already cached, seconds to
    write them)."""

    bytes: int
    seconds: float
    workers: dict[str, tuple[int, int, float]]


def ship(client: Any, shipment: Shipment, blobs: dict[str, bytes]) -> tuple[Shipment, ShippingCost]:
    """Send the files to every worker of ``client`` (and to each worker that joins while the study
    runs): the shipment naming its plugin, and what it cost.  :func:`unship` when the study ends."""
    # unique per study: two studies on one scheduler do not remove each other's plugin
    name = f"wmr-cosim-files-{os.getpid()}-{time.time_ns()}"
    plugin = FileShipping(name, blobs, shipment.names())
    t0 = time.perf_counter()
    client.register_plugin(plugin, name=name)
    seconds = time.perf_counter() - t0
    per = {w: r for w, r in client.run(_received, name).items() if r is not None}
    cost = ShippingCost(sum(len(b) for b in blobs.values()), seconds, per)
    return dataclasses.replace(shipment, plugin=name), cost


def unship(client: Any, shipment: Shipment) -> None:
    """Stop sending the study's files to joining workers (the scheduler lets the plugin go; the workers
    keep their cache)."""
    if shipment.plugin:
        try:
            client.unregister_worker_plugin(shipment.plugin)
        except Exception:   # (a scheduler already gone: nothing left to remove)
            pass
