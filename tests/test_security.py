"""Untrusted input and listening sockets: decompression bombs (an honest directory and one that lies about
sizes) refused with nothing written, XML entities (external: XXE; nested: billion laughs) refused in model
descriptions, SSDs and SSVs, archive limits settable in the scenario and on the command line, a local
sweep that listens on the loopback address only, and a sweep on a TLS scheduler with test certificates."""
from __future__ import annotations

import datetime
import ipaddress
import os
import re
import struct
import subprocess
import sys
import time
import urllib.error
import urllib.request
import zipfile
from pathlib import Path

import psutil
import pytest

from cosim_support import G1, g1_with_paths
from dask_support import free_port, stop
from wmr_cosim.cosim.model import archive
from wmr_cosim import cosim
from wmr_cosim.cosim.model.archive import ArchiveLimits, check_archive, safe_extract
from wmr_cosim.cosim.messages.errors import CosimError, FmuLoadError, ScenarioError
from wmr_cosim.cosim.model.description import load_model
from wmr_cosim.cosim.plan.ssp import export_ssp, load_ssp
from wmr_cosim.paper import robot_system

DATA = Path(__file__).parent / "data"
BOMB = 24 * 1024**2          # bytes of zeros in a bomb: deflates about 1000:1, to some 24 KiB
LOOPBACK = {"127.0.0.1", "::1"}


# ---------------------------------------------------------------------------------------------- helpers
def _cli(*args, env=None, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=timeout)


def _copy_with(src: Path, dst: Path, add=(), edit: dict | None = None) -> Path:
    """A copy of a zip archive with entries added ((name, bytes)) and entries edited ({name: text -> text})."""
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zo:
        for info in zi.infolist():
            data = zi.read(info)
            if edit and info.filename in edit:
                data = edit[info.filename](data.decode()).encode()
            zo.writestr(info, data)
        for name, data in add:
            zo.writestr(name, data)
    return dst


def _lie_about_size(path: Path, entry: str, declared: int) -> Path:
    """Patch the archive's central directory and local header so that ``entry`` declares ``declared``
    bytes unpacked (its data, and its CRC, unchanged)."""
    b = bytearray(path.read_bytes())
    name = entry.encode()
    patched = 0
    # (signature, offset of the uncompressed size, offset of the name length, header length)
    for sig, size_at, nlen_at, head in ((b"PK\x01\x02", 24, 28, 46), (b"PK\x03\x04", 22, 26, 30)):
        i = b.find(sig)
        while i >= 0:
            n = struct.unpack_from("<H", b, i + nlen_at)[0]
            if bytes(b[i + head:i + head + n]) == name:
                struct.pack_into("<I", b, i + size_at, declared)
                patched += 1
            i = b.find(sig, i + 4)
    assert patched == 2, patched
    path.write_bytes(bytes(b))
    return path


def _bomb(src: Path, dst: Path, lying: bool) -> Path:
    """``src`` with resources/zeros.bin, BOMB bytes of zeros, added; ``lying``: its directory declares 1 KiB."""
    _copy_with(src, dst, add=(("resources/zeros.bin", bytes(BOMB)),))
    return _lie_about_size(dst, "resources/zeros.bin", 1024) if lying else dst


def _tree(root: Path) -> list[Path]:
    return sorted(root.rglob("*"))


# ---------------------------------------------------------------------------------------------- bombs
def _stub(path: Path) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("modelDescription.xml", "<fmiModelDescription/>")
    return path


@pytest.mark.parametrize("lying", [False, True])
def test_a_bomb_is_refused_with_nothing_written(tmp_path, lying):
    box = tmp_path / "box"
    box.mkdir()
    bomb = _bomb(_stub(box / "plain.fmu"), box / "bomb.fmu", lying)
    info = zipfile.ZipFile(bomb).getinfo("resources/zeros.bin")
    assert info.file_size == (1024 if lying else BOMB) and info.compress_size < BOMB / 500
    expected = "inflates past the 1 KiB" if lying else r"a ratio of \d+:1 above the limit of 200:1"
    before = _tree(tmp_path)
    with pytest.raises(FmuLoadError, match=expected):
        check_archive(bomb)
    assert _tree(tmp_path) == before
    # extraction alone (the directory is not re-verified first): the lie is caught by counting bytes, into
    # a new folder (removed with its parent) and into an existing one (its own content kept)
    (box / "existing").mkdir()
    (box / "existing" / "mine.txt").write_text("kept")
    before = _tree(tmp_path)
    for dest in (box / "new" / "folder", box / "existing"):
        with pytest.raises(FmuLoadError, match=expected) as exc:
            safe_extract(bomb, dest)
        assert str(bomb) in str(exc.value) and "\n" not in str(exc.value)
        assert _tree(tmp_path) == before


def test_the_size_limit_and_how_to_raise_it(tmp_path):
    bomb = _bomb(_stub(tmp_path / "plain.fmu"), tmp_path / "bomb.fmu", lying=False)
    with pytest.raises(FmuLoadError, match="unpack to 24 MiB, more than the limit of 10 MiB.*--max-archive-size"):
        check_archive(bomb, ArchiveLimits(max_size=10 * 1024**2, max_ratio=1e6))
    out = safe_extract(bomb, tmp_path / "ok", ArchiveLimits(max_size=30 * 1024**2, max_ratio=2000))
    assert (out / "resources" / "zeros.bin").stat().st_size == BOMB
    # the same archive, small: below the ratio floor its ratio does not matter
    small = _copy_with(tmp_path / "plain.fmu", tmp_path / "small.fmu", add=(("z.bin", bytes(archive.RATIO_FLOOR - 100)),))
    assert (archive.RATIO_FLOOR - 100) / small.stat().st_size > 200
    check_archive(small)
    assert archive.parse_size("4 GiB") == 4 * 1024**3 and archive.parse_size("500MB") == 500_000_000
    assert archive.parse_size(1234) == 1234 and archive.fmt_size(2 * 1024**3) == "2 GiB"
    for bad in ("lots", "-1 GiB", "0", "4 GB/s", True):
        with pytest.raises(ValueError):
            archive.parse_size(bad)


@pytest.fixture(scope="module")
def bombs(built_fmus, tmp_path_factory):
    """An honest bomb (a stub FMU and 24 MiB of zeros: ratio about 1000:1) and a lying one (our sensor FMU and
    24 MiB of zeros its directory declares as 1 KiB)."""
    d = tmp_path_factory.mktemp("bombs")
    return {False: _bomb(_stub(d / "stub.fmu"), d / "WmrSensor-honest.fmu", lying=False),
            True: _bomb(built_fmus["WmrSensor"], d / "WmrSensor-lying.fmu", lying=True)}


@pytest.mark.parametrize("lying", [False, True])
def test_cli_refuses_a_bomb_fmu_in_a_scenario_and_alone(bombs, built_fmus, tmp_path, lying):
    work = tmp_path / "work"
    (work / "tmp").mkdir(parents=True)
    scen = g1_with_paths(work, {**built_fmus, "WmrSensor": bombs[lying]}, "[experiment]\nstop = 0.1\n")
    env = dict(os.environ, TMPDIR=str(work / "tmp"))     # every extraction folder would land here
    before = _tree(tmp_path)
    for args in (("run", scen, "--out", work / "out", "--quiet"), ("check", scen), ("info", bombs[lying])):
        p = _cli(*args, env=env)
        assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and "refused" in lines[0] and "WmrSensor" in lines[0], p.stderr
        assert ("inflates past" if lying else "ratio") in lines[0]
        assert _tree(tmp_path) == before


def test_limits_from_the_scenario_and_the_command_line(built_fmus, tmp_path):
    # our sensor FMU with 24 MiB of zeros: within the default limits (2 GiB, 200:1)
    fat = _copy_with(built_fmus["WmrSensor"], tmp_path / "WmrSensor.fmu", add=(("resources/zeros.bin", bytes(BOMB)),))
    with zipfile.ZipFile(fat) as zf:
        ratio = sum(i.file_size for i in zf.infolist()) / fat.stat().st_size
    assert 10 < ratio < 150, ratio
    fmus = {**built_fmus, "WmrSensor": fat}
    stop = "[experiment]\nstop = 0.1\n"
    plain = g1_with_paths(tmp_path, fmus, stop)
    tight = g1_with_paths(tmp_path, fmus, stop, name="tight.toml", head='[limits]\narchive_size = "8 MiB"\n')
    steep = g1_with_paths(tmp_path, fmus, stop, name="steep.toml", head="[limits]\narchive_ratio = 10\n")
    p = _cli("check", plain)
    assert p.returncode == 0, p.stderr
    p = _cli("check", tight)
    assert p.returncode == 2 and "more than the limit of 8 MiB" in p.stderr and "instances.sensor.fmu" in p.stderr
    p = _cli("check", steep)
    assert p.returncode == 2 and "above the limit of 10:1" in p.stderr, p.stderr
    p = _cli("--max-archive-size", "8MiB", "check", plain)
    assert p.returncode == 2 and "more than the limit of 8 MiB" in p.stderr, p.stderr
    p = _cli("--max-archive-ratio", str(int(ratio) + 10), "check", steep)   # the command line wins
    assert p.returncode == 0, p.stderr
    p = _cli("--max-archive-size", "lots", "check", plain)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "--max-archive-size" in p.stderr
    # in process: a bad [limits] names the file and the field; each scenario carries its own limits, and
    # its plan too; the caller's limits win over the scenario's, one by one
    bad = g1_with_paths(tmp_path, built_fmus, name="bad.toml", head="[limits]\narchive_size = -3\n")
    with pytest.raises(ScenarioError) as exc:
        cosim.load(bad)
    assert exc.value.field == "limits.archive_size"
    assert cosim.load(steep).archive_limits == ArchiveLimits(max_ratio=10)
    assert cosim.load(plain).archive_limits == ArchiveLimits()
    over = archive.LimitOverrides(max_size=3 * 1024**3)
    assert cosim.load(steep, limits=over).archive_limits == ArchiveLimits(3 * 1024**3, 10)
    assert cosim.resolve(cosim.load(plain, limits=archive.LimitOverrides(max_ratio=ratio + 10))
                          ).archive_limits == ArchiveLimits(max_ratio=ratio + 10)


@pytest.mark.parametrize("command, target", [
    (("paper", "--quiet"), "wmr_cosim.paper.run_paper"),
    (("sweep", "s.toml", "--quiet"), "wmr_cosim.studies.run_sweep"),
    (("gamma-search", "g.toml", "--quiet"), "wmr_cosim.paper.gamma_search")])
def test_the_commands_of_worker_processes_take_the_command_lines_limits_along(monkeypatch, tmp_path, command, target):
    """paper, sweep and gamma-search are given --max-archive-size and --max-archive-ratio as an argument
    (their workers get them with each job: tests/test_paper.py and tests/test_sweep.py run them), never
    refused up front; without the options, no limits.  (Each is replaced on the face the command line
    imports it from.)"""
    import importlib

    from wmr_cosim import cli

    monkeypatch.chdir(tmp_path)
    for name in ("s.toml", "g.toml"):
        (tmp_path / name).write_text("")
    given: list = []

    def stand_in(*args, **kw):
        given.append(kw["archive_limits"])
        raise CosimError("stand-in: stop here")

    module, name = target.rsplit(".", 1)
    monkeypatch.setattr(importlib.import_module(module), name, stand_in)
    assert cli.main(["--max-archive-size", "3MiB", "--max-archive-ratio", "50", *command]) == 2
    assert cli.main(list(command)) == 2
    assert given == [archive.LimitOverrides(max_size=3 * 1024**2, max_ratio=50.0), None]


def test_two_scenarios_read_one_after_the_other_extract_each_with_its_own_limits(tmp_path):
    """The limits travel with the scenario and its plan, not with the module: a scenario read later does
    not change the limits an earlier one is resolved and extracted with."""
    from reference_fmus import REF

    fat = tmp_path / "Dahlquist.fmu"     # 4 MiB more, stored (ratio about 1: within the default limits)
    with zipfile.ZipFile(REF / "fmi2" / "Dahlquist.fmu") as zi, zipfile.ZipFile(fat, "w") as zo:
        for info in zi.infolist():
            zo.writestr(info, zi.read(info))
        zo.writestr("resources/zeros.bin", bytes(4 * 1024**2))
    doc = {"experiment": {"stop": 0.1, "step": 0.05}, "instances": {"a": {"fmu": str(fat)}}}
    tight = cosim.parse({**doc, "limits": {"archive_size": "1 MiB"}}, "tight.toml")
    loose = cosim.parse({**doc, "limits": {"archive_size": "1 GiB"}}, "loose.toml")
    with pytest.raises(ScenarioError, match="instances.a.fmu: .*more than the limit of 1 MiB"):
        cosim.resolve(tight)
    plan = cosim.resolve(loose)
    assert plan.archive_limits == ArchiveLimits(max_size=1024**3)
    assert (safe_extract(fat, tmp_path / "loose", plan.archive_limits) / "resources" / "zeros.bin").is_file()
    with pytest.raises(FmuLoadError, match="more than the limit of 1 MiB"):
        safe_extract(fat, tmp_path / "tight", tight.archive_limits)
    assert not (tmp_path / "tight").exists()


def test_a_limit_raised_above_the_default_lets_a_compressed_fmu_run(tmp_path):
    """An FMU whose resources compress 1000 to 1 (over the default ratio of 200) is refused by default and
    runs with a scenario's ``[limits] archive_ratio`` above it: loading the model checks the scenario's
    limits, not the default ones."""
    from reference_fmus import REF

    dense = tmp_path / "Dahlquist.fmu"
    with zipfile.ZipFile(REF / "fmi2" / "Dahlquist.fmu") as zi, \
            zipfile.ZipFile(dense, "w", zipfile.ZIP_DEFLATED) as zo:
        for info in zi.infolist():
            zo.writestr(info, zi.read(info))
        zo.writestr("resources/zeros.bin", bytes(8 * 1024**2))
    doc = {"experiment": {"stop": 0.1, "step": 0.05}, "instances": {"a": {"fmu": str(dense)}}}
    with pytest.raises(ScenarioError, match="ratio"):
        cosim.resolve(cosim.parse(doc, "default.toml"))
    plan = cosim.resolve(cosim.parse({**doc, "limits": {"archive_ratio": 1e5}}, "raised.toml"))
    res = cosim.run(plan, None, progress=False)
    assert res.status == "ok" and res.steps == 2, res.message


# ---------------------------------------------------------------------------------------------- SSP
@pytest.fixture(scope="module")
def g1_ssp(built_fmus, tmp_path_factory):
    sc = cosim.load(G1, lambda name: built_fmus.get(name))
    return export_ssp(cosim.resolve(sc), tmp_path_factory.mktemp("ssp") / "g1.ssp")


def test_a_bomb_ssp_or_a_bomb_fmu_inside_one_is_refused(g1_ssp, bombs, tmp_path):
    work = tmp_path / "work"
    (work / "tmp").mkdir(parents=True)
    with zipfile.ZipFile(g1_ssp) as zi, zipfile.ZipFile(work / "inner.ssp", "w") as zo:
        for info in zi.infolist():
            data = bombs[False].read_bytes() if info.filename == "resources/WmrSensor.fmu" else zi.read(info)
            zo.writestr(info, data)
    outer = _lie_about_size(_copy_with(g1_ssp, work / "outer.ssp", add=(("resources/zeros.bin", bytes(BOMB)),)),
                            "resources/zeros.bin", 1024)
    env = dict(os.environ, TMPDIR=str(work / "tmp"))
    before = _tree(tmp_path)
    for target, expected in ((work / "inner.ssp", "WmrSensor.fmu in the archive: refused"),
                             (outer, "inflates past")):
        with pytest.raises(ScenarioError, match=expected):
            load_ssp(target)
        p = _cli("run", target, "--out", work / "out", "--quiet", env=env)
        assert p.returncode == 2 and expected in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert _tree(tmp_path) == before


# ---------------------------------------------------------------------------------------------- XML
def _doctype(text: str, root: str, decl: str) -> str:
    text = re.sub(r"^<\?xml[^>]*\?>\s*", "", text)
    return f'<?xml version="1.0" encoding="UTF-8"?>\n<!DOCTYPE {root} [{decl}]>\n{text}'


def _entities(kind: str, secret: Path) -> tuple[str, str]:
    """(declarations, reference) of an external entity reading ``secret`` or of a billion laughs."""
    if kind == "xxe":
        return f'<!ENTITY xxe SYSTEM "file://{secret}">', "&xxe;"
    decl = '<!ENTITY lol0 "lol">' + "".join(f'<!ENTITY lol{i} "{("&lol%d;" % (i - 1)) * 10}">' for i in range(1, 10))
    return decl, "&lol9;"


@pytest.mark.parametrize("kind", ["xxe", "billion_laughs"])
def test_a_model_description_with_entities_is_refused(built_fmus, tmp_path, kind):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET")
    decl, ref = _entities(kind, secret)

    def edit(text: str) -> str:
        i = text.index("<ScalarVariable")                          # deep in the document, not at its root
        j = text.index('description="', i) + len('description="')
        return _doctype(text[:j] + ref + text[j:], "fmiModelDescription", decl)

    evil = _copy_with(built_fmus["WmrSensor"], tmp_path / "evil.fmu", edit={"modelDescription.xml": edit})
    with pytest.raises(FmuLoadError, match="declares the XML entity '(xxe|lol0)': refused") as exc:
        load_model(evil)
    assert "TOPSECRET" not in str(exc.value)
    p = _cli("info", evil)
    assert p.returncode == 2 and "declares the XML entity" in p.stderr and "TOPSECRET" not in p.stdout + p.stderr


@pytest.mark.parametrize("kind", ["xxe", "billion_laughs"])
@pytest.mark.parametrize("doc", ["SystemStructure.ssd", "resources/controller.ssv"])
def test_an_ssd_or_ssv_with_entities_is_refused(g1_ssp, tmp_path, kind, doc):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET")
    decl, ref = _entities(kind, secret)
    root = "ssd:SystemStructureDescription" if doc.endswith(".ssd") else "ssv:ParameterSet"

    def edit(text: str) -> str:
        # the reference as text after the first System/Parameter start tag (libxml2 itself refuses an
        # external entity in an attribute)
        return _doctype(re.sub(r"<(ssd:System|ssv:Parameter)\b[^>]*>", lambda m: m.group(0) + ref, text, count=1),
                        root, decl)

    evil = _copy_with(g1_ssp, tmp_path / "evil.ssp", edit={doc: edit})
    # (libxml2 itself stops the billion laughs while parsing, before the entity check: either refusal will do)
    expected = "declares the XML entity 'xxe': refused" if kind == "xxe" else \
        "(declares the XML entity 'lol0': refused|entity amplification factor exceeded)"
    with pytest.raises(ScenarioError, match=expected) as exc:
        load_ssp(evil)
    assert doc.split("/")[-1] in str(exc.value) and "TOPSECRET" not in str(exc.value)


# ---------------------------------------------------------------------------------------------- Dask
def _listening(pids: list[int]) -> set[tuple[int, str, int]]:
    """(pid, address, port) of every listening TCP socket of the processes ``pids`` and their children."""
    seen: set[tuple[int, str, int]] = set()
    procs: list[psutil.Process] = []
    for pid in pids:
        try:
            p = psutil.Process(pid)
            procs += [p, *p.children(recursive=True)]
        except psutil.NoSuchProcess:
            pass
    for p in procs:
        try:
            for c in p.net_connections(kind="inet"):
                if c.status == psutil.CONN_LISTEN:
                    seen.add((p.pid, c.laddr.ip, c.laddr.port))
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            pass
    return seen


@pytest.fixture(scope="module")
def sweep_fmus(built_fmus):
    """The points of an in-process sweep run on the session's FMUs."""
    from wmr_cosim import runner

    mp = pytest.MonkeyPatch()
    mp.setattr(runner, "resolve_model", lambda name: built_fmus.get(name))
    yield
    mp.undo()


ONE_POINT = 'runs = ["learn"]\n[grid]\n"plant.foam_da1" = [0.4]\n'


def _sweep_file(tmp: Path) -> Path:
    f = tmp / "sweep-one.toml"
    f.write_text(f'base = "{DATA / "short_protocol.toml"}"\n{ONE_POINT}')
    return f


@pytest.mark.parametrize("dashboard", [False, True])
def test_a_local_cluster_listens_on_the_loopback_address_only(tmp_path, dashboard, sweep_fmus, capsys):
    from wmr_cosim.studies import cluster, sweep

    with cluster.Cluster(workers=1, dashboard=dashboard) as cl:
        df = sweep.run_sweep(_sweep_file(tmp_path), tmp_path / "out", cluster=cl, progress=False, system=robot_system())
        socks = _listening([os.getpid()])
        http_port = cl.cluster.scheduler.http_server.port
        assert (os.getpid(), "127.0.0.1", http_port) in socks          # the scheduler's HTTP endpoint
        try:
            status = urllib.request.urlopen(f"http://127.0.0.1:{http_port}/status", timeout=10).status
        except urllib.error.HTTPError as exc:
            status = exc.code
    assert list(df["status"]) == ["ok"]
    pids = {pid for pid, _, _ in socks}
    assert len(socks) >= 4 and len(pids) >= 2, socks                  # scheduler, nanny, worker, HTTP
    assert {ip for _, ip, _ in socks} <= LOOPBACK, socks
    if dashboard:
        assert status == 200 and cl.dashboard == f"http://127.0.0.1:{http_port}/status"
        assert f"dask dashboard: {cl.dashboard}" in capsys.readouterr().err
    else:
        assert status == 404 and cl.dashboard is None


def test_the_sweep_command_listens_on_the_loopback_address_only(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("DASK_")}
    proc = subprocess.Popen([sys.executable, "-m", "wmr_cosim.cli", "sweep", str(_sweep_file(tmp_path)), "--out",
                             str(tmp_path / "out"), "--workers", "2", "--dashboard", "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    socks: set[tuple[int, str, int]] = set()
    try:
        while proc.poll() is None:
            socks |= _listening([proc.pid])
            time.sleep(0.1)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0 and "1 point (1 ok)" in out, err
    m = re.search(r"dask dashboard: http://127\.0\.0\.1:(\d+)/status", err)
    assert m, err
    assert (proc.pid, "127.0.0.1", int(m.group(1))) in socks
    assert len({pid for pid, _, _ in socks}) >= 3, socks              # the command and its two workers
    assert {ip for _, ip, _ in socks} <= LOOPBACK, socks


# ---------------------------------------------------------------------------------------------- TLS
def _certificates(d: Path) -> dict[str, Path]:
    """A test CA and one certificate it signed (for 127.0.0.1 and localhost), used by the scheduler, the
    workers and the client alike: {'ca', 'cert', 'key'} PEM files."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.timezone.utc)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "wmr-cosim test CA")])
    ca = (x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
          .not_valid_after(now + datetime.timedelta(days=1))
          .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
          .sign(ca_key, hashes.SHA256()))
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")]))
            .issuer_name(ca_name).public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5)).not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName("localhost"),
                                                        x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                           critical=False)
            .sign(ca_key, hashes.SHA256()))
    files = {"ca": d / "ca.pem", "cert": d / "cert.pem", "key": d / "key.pem"}
    files["ca"].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    files["cert"].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    files["key"].write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                               serialization.NoEncryption()))
    return files


def test_a_clear_text_scheduler_beyond_this_machine_is_warned_about():
    from wmr_cosim.studies.cluster import cleartext_warning

    assert "neither encrypted nor authenticated" in cleartext_warning("tcp://10.0.0.5:8786")
    assert "use tls://" in cleartext_warning("tcp://[2001:db8::1]:8786")
    for quiet in ("tcp://127.0.0.1:8786", "tcp://localhost:8786", "tcp://[::1]:8786", "tls://10.0.0.5:8786"):
        assert cleartext_warning(quiet) is None, quiet


def test_a_sweep_on_a_tls_scheduler(tmp_path):
    from distributed import Client

    from wmr_cosim.studies.cluster import dask_security

    certs = _certificates(tmp_path)
    tls = ["--tls-ca-file", str(certs["ca"]), "--tls-cert", str(certs["cert"]), "--tls-key", str(certs["key"])]
    port = free_port()
    addr = f"tls://127.0.0.1:{port}"
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("DASK_")},
           "DASK_DISTRIBUTED__WORKER__DAEMON": "True",
           "DASK_TEMPORARY_DIRECTORY": str(tmp_path / "dask")}  # the scheduler's dask-scratch-space, not in TMPDIR
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--protocol", "tls", "--no-dashboard", *tls],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)]
    try:
        time.sleep(1.0)
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", addr, "--nthreads", "1",
                                       "--no-dashboard", "--local-directory", str(tmp_path / "w"), *tls],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
        sec = dask_security(str(certs["ca"]), str(certs["cert"]), str(certs["key"]))
        with Client(addr, security=sec, timeout="20s") as c:
            c.wait_for_workers(1, timeout=60)
            assert all(w.startswith("tls://") for w in c.scheduler_info()["workers"])
        f = _sweep_file(tmp_path)
        p = _cli("sweep", f, "--out", tmp_path / "out", "--scheduler", addr, "--quiet", *tls, env=env)
        assert p.returncode == 0 and "1 point (1 ok)" in p.stdout, p.stderr
        # without the certificates, or in clear text, the scheduler cannot be used
        for args in (("--scheduler", addr), ("--scheduler", f"tcp://127.0.0.1:{port}")):
            p = _cli("sweep", f, "--out", tmp_path / "out2", "--quiet", *args, env=env, timeout=120)
            assert p.returncode == 2 and "cannot connect" in p.stderr, p.stderr
            assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
        p = _cli("sweep", f, "--out", tmp_path / "out3", "--scheduler", addr, "--tls-cert", certs["cert"], env=env)
        assert p.returncode == 2 and "--tls-ca-file: missing" in p.stderr, p.stderr
    finally:
        stop(procs)


@pytest.mark.parametrize("value, message", [
    (True, "True is not a size"),
    ("lots", "'lots' is not a size (a number of bytes, or e.g. '4 GiB', '500 MB')"),
    ("4 GB/s", "'4 GB/s' is not a size (a number of bytes, or e.g. '4 GiB', '500 MB')"),
    ("0", "'0': a size must be at least 1 byte"),
    (0.5, "0.5: a size must be at least 1 byte")])
def test_a_size_limit_that_is_not_a_size_is_named_in_one_line(value, message):
    with pytest.raises(ValueError) as err:
        archive.parse_size(value)
    assert str(err.value) == message


def test_a_ratio_limit_is_a_number_of_at_least_one():
    assert archive.parse_ratio(1) == 1.0 and archive.parse_ratio("2.5") == 2.5
    for bad in (1 - 1e-12, 0, True, "x", None, float("inf"), float("nan")):
        with pytest.raises(ValueError) as err:
            archive.parse_ratio(bad)
        assert str(err.value) == f"{bad!r}: a ratio limit must be a number >= 1"


def test_a_failed_extraction_into_an_existing_folder_removes_the_folders_it_made(tmp_path):
    """Directory entries made before a member fails (here its CRC does not match) are removed again; the
    folder that was there before stays, with what it held."""
    src = tmp_path / "bad.zip"
    with zipfile.ZipFile(src, "w", zipfile.ZIP_STORED) as zf:
        zf.writestr(zipfile.ZipInfo("docs/"), b"")
        zf.writestr(zipfile.ZipInfo("docs/sub/"), b"")
        zf.writestr("resources/a.txt", b"hello world")
    src.write_bytes(src.read_bytes().replace(b"hello world", b"HELLO WORLD"))
    dest = tmp_path / "dest"
    dest.mkdir()
    (dest / "mine.txt").write_text("kept")
    with pytest.raises(Exception):
        archive.safe_extract(src, dest)
    assert sorted(p.name for p in dest.iterdir()) == ["mine.txt"]


def test_a_lying_directory_is_named_with_its_archive_by_the_check(tmp_path):
    """check_archive decompresses every entry (nothing written): an entry that inflates past the size the
    directory declares is refused, the message naming the archive and the entry."""
    liar = _bomb(_stub(tmp_path / "stub.fmu"), tmp_path / "liar.fmu", lying=True)
    with pytest.raises(FmuLoadError) as err:
        check_archive(liar)
    assert str(err.value) == (f"{liar}: refused: entry 'resources/zeros.bin' inflates past the 1 KiB the archive's "
                              "directory declares (a decompression bomb?)")
