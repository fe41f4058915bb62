"""Safe extraction of zip archives (FMU, SSP): every entry is checked before anything is written.

Refused: absolute paths, drive letters, '..' components, backslash tricks, and symbolic links (FMPy's
extract refuses only absolute paths; Python's zipfile silently rewrites '../x' to 'x'; a symlink entry
becomes a plain file).  A '..' anywhere in an entry's path is refused, also one that stays inside the
folder ('resources/a/../b'): no tool writes such names, and one rule with nothing to work out leaves
nothing to get wrong; the message says whether the entry would have escaped.

Decompression bombs are refused too.  An archive whose directory declares more than ``max_size`` bytes
unpacked in all, or more than ``max_ratio`` times the archive's size on disk, is refused from its
directory alone, before anything is written.  Since a directory can lie about sizes, the bytes are also
counted as each entry is decompressed (when the archive is verified and when it is extracted): an entry
that inflates past the size its directory declares, or a total past ``max_size``, stops the extraction
at once and removes what was written.

The limits (:class:`ArchiveLimits`) are an explicit argument of every check and extraction (the defaults,
2 GiB and 200:1, when none is given).  A scenario carries its own (``Scenario.archive_limits``, from its
``[limits]`` table: :func:`parse_limits`) and so does the plan resolved from it (``Plan.archive_limits``);
a caller's own limits (:class:`LimitOverrides`, such as a command line's options) win over the
scenario's, one by one.  Nothing is kept between calls: two scenarios read one after the other each
extract with their own limits.  Both kinds are plain values that pickle: work run in other processes
(the paper job's, a sweep's) takes them with each job.
"""
from __future__ import annotations

import copy
import math
import os
import re
import shutil
import stat
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import IO, Any, Callable

from ..messages.errors import CosimError, FmuLoadError, ScenarioError
from ..messages.suggest import unknown_key

KiB, MiB, GiB, TiB = 1024, 1024**2, 1024**3, 1024**4
#: Default limit on the sum of an archive's unpacked entry sizes [bytes].
DEFAULT_MAX_SIZE = 2 * GiB
#: Default limit on unpacked size / archive size on disk [-].  Real FMUs stay far below (pythonfmu
#: stores its entries uncompressed, ratio 1; compiled binaries and XML deflate by 3 to 20).
DEFAULT_MAX_RATIO = 200.0
#: Archives that unpack to at most this many bytes are never refused for their ratio: they cannot fill
#: a disk, and small text files alone can compress well [bytes].
RATIO_FLOOR = 1 * MiB
_CHUNK = 1 * MiB
_UNITS = {"": 1, "b": 1, "k": 1000, "kb": 1000, "mb": 1000**2, "gb": 1000**3, "tb": 1000**4,
          "kib": KiB, "mib": MiB, "gib": GiB, "tib": TiB}
_HOW_TO_RAISE = {"max_size": "--max-archive-size or [limits] archive_size",
                 "max_ratio": "--max-archive-ratio or [limits] archive_ratio"}


@dataclass(frozen=True)
class ArchiveLimits:
    """How far an archive may unpack: ``max_size`` [bytes] in all, ``max_ratio`` [-] times its size on disk."""

    max_size: int = DEFAULT_MAX_SIZE
    max_ratio: float = DEFAULT_MAX_RATIO


#: The limits of an archive nobody set limits for.
DEFAULT_LIMITS = ArchiveLimits()


@dataclass(frozen=True)
class LimitOverrides:
    """Limits a caller sets over a scenario's own (a command line's options): each one given (not None)
    wins over the scenario's ``[limits]``; one not given leaves the scenario's, else the default."""

    max_size: int | None = None
    max_ratio: float | None = None

    def over(self, limits: ArchiveLimits = DEFAULT_LIMITS) -> ArchiveLimits:
        """``limits`` with the ones given here put in their place."""
        return ArchiveLimits(limits.max_size if self.max_size is None else self.max_size,
                             limits.max_ratio if self.max_ratio is None else self.max_ratio)


# ---------------------------------------------------------------------------------------------- limits
def parse_size(value: Any) -> int:
    """A size in bytes from an integer or a text such as ``"4 GiB"``, ``"500MB"``, ``"1e9"`` (units B, kB, MB,
    GB, TB powers of 1000; KiB, MiB, GiB, TiB powers of 1024).  ValueError if it is not a size > 0."""
    if isinstance(value, bool):
        raise ValueError(f"{value!r} is not a size")
    if isinstance(value, (int, float)):
        n = float(value)
    else:
        m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*", str(value))
        if not m or m.group(2).lower() not in _UNITS:
            raise ValueError(f"{value!r} is not a size (a number of bytes, or e.g. '4 GiB', '500 MB')")
        n = float(m.group(1)) * _UNITS[m.group(2).lower()]
    if not math.isfinite(n) or n < 1:
        raise ValueError(f"{value!r}: a size must be at least 1 byte")
    return int(n)


def parse_ratio(value: Any) -> float:
    """A ratio limit (a number >= 1); ValueError otherwise."""
    try:
        r = float(value) if not isinstance(value, bool) else math.nan
    except (TypeError, ValueError):
        r = math.nan
    if not math.isfinite(r) or r < 1:
        raise ValueError(f"{value!r}: a ratio limit must be a number >= 1")
    return r


def fmt_size(n: float) -> str:
    """Bytes as text with a binary unit: 2147483648 -> '2 GiB'."""
    for unit, f in (("TiB", TiB), ("GiB", GiB), ("MiB", MiB), ("KiB", KiB)):
        if n >= f:
            return f"{n / f:.4g} {unit}"
    return f"{int(n)} B"


def parse_limits(file: str, table: Any, over: LimitOverrides | None = None) -> ArchiveLimits:
    """The limits of a scenario: its ``[limits]`` table (``archive_size``: a size, ``archive_ratio``: a
    number; None when it has none) over the defaults, and ``over`` over both.  ScenarioError for a bad value."""
    if table is None:
        table = {}
    if not isinstance(table, dict):
        raise ScenarioError(file, "limits", "must be a table (archive_size, archive_ratio)")
    given: dict[str, Any] = {}
    for k, v in table.items():
        try:
            if k == "archive_size":
                given["max_size"] = parse_size(v)
            elif k == "archive_ratio":
                given["max_ratio"] = parse_ratio(v)
            else:
                raise ScenarioError(file, f"limits.{k}", unknown_key(k, ("archive_ratio", "archive_size")))
        except ValueError as exc:
            raise ScenarioError(file, f"limits.{k}", str(exc)) from None
    own = ArchiveLimits(**given)
    return over.over(own) if over is not None else own


def limit_overrides(max_size: Any = None, max_ratio: Any = None, names: tuple[str, str] = ("max_size", "max_ratio")
                    ) -> LimitOverrides:
    """A caller's limits from their text (``max_size`` a size such as ``"8 GiB"``, ``max_ratio`` a number;
    None: not given).  CosimError naming the value (by ``names``: a command line gives its options' names)."""
    parsed: list[Any] = []
    for name, value, parse in ((names[0], max_size, parse_size), (names[1], max_ratio, parse_ratio)):
        try:
            parsed.append(None if value is None else parse(value))
        except ValueError as exc:
            raise CosimError(f"{name}: {exc}") from None
    return LimitOverrides(*parsed)


def check_sizes(label: str, infos: list[zipfile.ZipInfo], archive_size: int,
                limits: ArchiveLimits | None = None) -> None:
    """FmuLoadError naming ``label`` if the entries' declared sizes pass the limits: their sum above
    ``max_size``, or (above :data:`RATIO_FLOOR`) above ``max_ratio`` times ``archive_size`` [bytes]."""
    lim = limits or DEFAULT_LIMITS
    total = sum(i.file_size for i in infos)
    if total > lim.max_size:
        raise FmuLoadError(f"{label}: refused: its entries unpack to {fmt_size(total)}, more than the limit of "
                           f"{fmt_size(lim.max_size)} (a decompression bomb?); raise it with {_HOW_TO_RAISE['max_size']}")
    ratio = total / max(archive_size, 1)
    if total > RATIO_FLOOR and ratio > lim.max_ratio:
        raise FmuLoadError(f"{label}: refused: {fmt_size(archive_size)} unpack to {fmt_size(total)}, a ratio of "
                           f"{ratio:.0f}:1 above the limit of {lim.max_ratio:g}:1 (a decompression bomb?); raise it "
                           f"with {_HOW_TO_RAISE['max_ratio']}")


# ---------------------------------------------------------------------------------------------- checks
def check_archive(path: str | os.PathLike, limits: ArchiveLimits | None = None,
                  verify: bool = True) -> list[zipfile.ZipInfo]:
    """The archive's entries, or FmuLoadError naming the archive and the first unsafe entry or the limit
    it passes.  ``verify`` also decompresses every entry (nothing written) to catch a directory that lies
    about sizes."""
    path = Path(path)
    if not path.is_file():
        raise FmuLoadError(f"{path}: file not found")
    lim = limits or DEFAULT_LIMITS
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise FmuLoadError(f"{path}: not a zip archive ({exc})") from None
    with zf:
        infos = zf.infolist()
        check_entries(str(path), infos)
        check_sizes(str(path), infos, path.stat().st_size, lim)
        if verify:
            budget = [lim.max_size]
            for info in infos:
                if not info.is_dir():
                    _copy_member(str(path), zf, info, None, budget)
    return infos


def check_entries(label: str, infos: list[zipfile.ZipInfo]) -> None:
    """FmuLoadError naming ``label`` and the first entry that is absolute, has a '..' component anywhere in
    its path (whether or not it would climb out of the folder) or is a link."""
    for info in infos:
        name = info.filename
        p = PurePosixPath(name.replace("\\", "/"))
        mode = (info.external_attr >> 16) & 0xFFFF
        if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":"):
            raise FmuLoadError(f"{label}: refused: entry '{name}' has an absolute path")
        if ".." in p.parts:
            why = "would extract outside its folder" if escapes(p.parts) else \
                "has a '..' component (refused even where it stays inside the folder)"
            raise FmuLoadError(f"{label}: refused: entry '{name}' {why}")
        if stat.S_ISLNK(mode):
            raise FmuLoadError(f"{label}: refused: entry '{name}' is a symbolic link")


def escapes(parts: tuple[str, ...]) -> bool:
    """Whether a relative path of these parts (a PurePosixPath's: no '.' or empty ones), normalised, climbs
    above its folder ('a/../../x' does, 'a/../x' and 'a/..' do not)."""
    depth = 0
    for part in parts:
        depth += -1 if part == ".." else 1
        if depth < 0:
            return True
    return False


def _copy_member(label: str, zf: zipfile.ZipFile, info: zipfile.ZipInfo, sink: IO[bytes] | None,
                 budget: list[int]) -> int:
    """Decompress one entry into ``sink`` (None: count only), counting bytes: FmuLoadError as soon as it
    inflates past its declared size or past what is left of ``budget[0]`` [bytes].  Returns its size."""
    declared = info.file_size
    bounded = copy.copy(info)
    # zipfile stops an entry at its declared size; one byte more shows whether the data goes on
    bounded.file_size = min(declared, budget[0]) + 1
    bounded.CRC = None  # type: ignore[assignment]  # (else zipfile checks it at that byte, before the count)
    n = crc = 0
    try:
        with zf.open(bounded) as src:
            while True:
                chunk = src.read(_CHUNK)
                if not chunk:
                    break
                n += len(chunk)
                if n > declared:
                    raise FmuLoadError(f"{label}: refused: entry '{info.filename}' inflates past the "
                                       f"{fmt_size(declared)} the archive's directory declares (a decompression "
                                       "bomb?)")
                if n > budget[0]:
                    raise FmuLoadError(f"{label}: refused: unpacking passes the limit of {fmt_size(budget[0])} "
                                       f"(a decompression bomb?); raise it with {_HOW_TO_RAISE['max_size']}")
                crc = zlib.crc32(chunk, crc)
                if sink is not None:
                    sink.write(chunk)
        if crc != info.CRC:
            raise zipfile.BadZipFile("bad CRC-32")
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError, OSError, ValueError,
            zlib.error) as exc:   # zlib.error: compressed data no inflater accepts
        raise FmuLoadError(f"{label}: entry '{info.filename}' cannot be read "
                           f"({' '.join(str(exc).split()) or type(exc).__name__})") from None
    budget[0] -= n
    return n


def run_members(platform: str) -> Callable[[str], bool]:
    """Which entries of an FMU a run needs unpacked: ``modelDescription.xml``, ``resources/`` and the
    binaries of ``platform`` (``binaries/<platform>/``: the shared library and what it loads).  An FMU may
    assume nothing of the folder outside its resources (FMI 2.0 2.3, FMI 3.0 2.5); sources, documentation,
    ``extra/`` and other platforms' binaries stay packed (each file written costs a create)."""
    binaries = f"binaries/{platform}/"

    def needed(name: str) -> bool:
        parts = [p for p in PurePosixPath(name.replace("\\", "/")).parts if p not in ("", ".")]
        path = "/".join(parts) + "/"
        return path == "modelDescription.xml/" or path.startswith(("resources/", binaries)) or \
            binaries.startswith(path)
    return needed


def safe_extract(path: str | os.PathLike, dest: str | os.PathLike, limits: ArchiveLimits | None = None,
                 only: Callable[[str], bool] | None = None) -> Path:
    """Check the whole archive, then extract it (its entries that ``only`` keeps, None: all) into ``dest``
    (created), counting the bytes written; returns ``dest``.  On any refusal what was written is removed
    (``dest`` too if it did not exist)."""
    lim = limits or DEFAULT_LIMITS
    infos = check_archive(path, lim, verify=False)
    if only is not None:
        infos = [i for i in infos if only(i.filename)]
    dest = Path(dest)
    top = dest                         # the first folder this call creates: removed on failure
    while not top.parent.exists():
        top = top.parent
    existed = dest.exists()
    dest.mkdir(parents=True, exist_ok=True)
    root = dest.resolve()
    written: list[Path] = []
    made: list[Path] = []
    ok = False
    try:
        for info in infos:
            target = (dest / info.filename).resolve()
            if root != target and root not in target.parents:  # belt and braces
                raise FmuLoadError(f"{path}: refused: entry '{info.filename}' would extract outside its folder")
        budget = [lim.max_size]
        with zipfile.ZipFile(path) as zf:
            for info in infos:
                parts = [p for p in PurePosixPath(info.filename).parts if p not in ("", ".")]
                if not parts:
                    continue
                target = dest.joinpath(*parts)
                for d in reversed([target.parent, *target.parent.parents]):
                    if d.is_relative_to(dest) and not d.exists():
                        d.mkdir()
                        made.append(d)
                if info.is_dir():
                    if not target.exists():
                        target.mkdir()
                        made.append(target)
                    continue
                with open(target, "wb") as fh:
                    written.append(target)
                    _copy_member(str(path), zf, info, fh, budget)
        ok = True
    finally:
        if not ok:
            if not existed:
                shutil.rmtree(top, ignore_errors=True)
            else:
                for f in written:
                    f.unlink(missing_ok=True)
                for d in reversed(made):
                    shutil.rmtree(d, ignore_errors=True)
    return dest
