"""The output guard: what a command writes, checked against what it reads, before anything is written.

One rule for every brdfcorr command and chain (:func:`check_outputs`):

1. an output is a regular file or absent: a directory, device, FIFO or socket is refused;
2. an output is not the same file as any input: inputs are never overwritten;
3. no two outputs are the same file (the second would replace the first);
4. the files GDAL reads beside an input raster (:func:`sidecar_paths`: an ENVI header in both
   namings ``NAME.hdr`` and ``NAME.ext.hdr``, ``.aux.xml``, ``.ovr``, ``.msk``) are inputs too:
   where they exist, ``correct in.img -o in.img.bsq --format ENVI`` would write its header over the
   input's ``in.img.hdr``; where they do not, an output there would become the input's sidecar
   (GDAL opens ``in.bil`` with ``in.bil.hdr`` in preference to ``in.hdr``, so the header of an
   output ``in.bil.img`` would scramble every later read of the input) and is refused as well
   (:class:`SidecarClashError`). The sidecars an output writes are named by the caller (an ENVI
   output's header and ``.aux.xml``, :func:`brdfcorr.io.writer.envi_sidecars`).

"The same file" is decided by file identity where both paths exist (``os.stat``: device and inode,
through symbolic links, so a link to an input or a hard link of it is that input), and by the
resolved path otherwise (an output not yet written is the input of the same path). Paths are shown
as the user gave them; identity is only compared here.

:func:`remove_partials` removes the temporary files an interrupted run left beside its outputs
(the names of :func:`brdfcorr.io.files.atomic_path`); :func:`check_format` refuses an output whose
file name extension belongs to another format.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
from collections.abc import Iterable, Mapping
from pathlib import Path

from brdfcorr.errors import InputError, OutputError
from brdfcorr.io import EXTENSIONS, FORMATS

__all__ = ["check_outputs", "check_format", "sidecar_paths", "same_file", "file_identity", "refuse_existing",
           "update_target", "remove_partials", "envi_header_path", "envi_sidecars", "stale_sidecars",
           "raster_files", "InputOverwriteError",
           "SidecarClashError", "SameOutputError"]

PathLike = str | os.PathLike
Named = Mapping[str, PathLike | None] | Iterable[PathLike | tuple[str, PathLike | None] | None]


class InputOverwriteError(InputError):
    """An output is the same file as an input (attributes: ``output_name``, ``output``,
    ``input_name``, ``input``)."""

    def __init__(self, output_name: str, output: PathLike, input_name: str, input: PathLike,
                 message: str | None = None):
        self.output_name, self.output, self.input_name, self.input = output_name, output, input_name, input
        super().__init__(message or f"{_describe(output_name, output)} is also an input; inputs are never "
                                    f"overwritten (the same file as {_describe(input_name, input)})")


#: What GDAL reads from a sidecar, by the end of its name (:func:`sidecar_paths`).
_SIDECAR_KINDS = {".hdr": "ENVI header", ".aux.xml": "tags and statistics (.aux.xml)", ".ovr": "overviews",
                  ".msk": "mask"}


class SidecarClashError(InputOverwriteError):
    """An output is a file GDAL would read beside an input (:func:`sidecar_paths`) that does not
    exist yet: once written, it would become the input's header, tags, overviews or mask
    (attributes as :class:`InputOverwriteError`, ``input`` the raster; ``sidecar``: the path)."""

    def __init__(self, output_name: str, output: PathLike, input_name: str, input: PathLike, sidecar: PathLike):
        self.sidecar = sidecar
        kind = next((what for end, what in _SIDECAR_KINDS.items() if str(sidecar).lower().endswith(end)), "sidecar")
        super().__init__(output_name, output, input_name, input,
                         f"{_describe(output_name, output)} would become the {kind} GDAL reads with "
                         f"{_describe(input_name, input)} and change what it reads; give the output another name")


class SameOutputError(OutputError):
    """Two outputs are the same file (attributes: ``output_name``, ``output``, ``other_name``,
    ``other``)."""

    def __init__(self, output_name: str, output: PathLike, other_name: str, other: PathLike):
        self.output_name, self.output, self.other_name, self.other = output_name, output, other_name, other
        super().__init__(f"{_describe(output_name, output)} and {_describe(other_name, other)} are the same "
                         "file; give each output its own file")


def _describe(name: str, path: PathLike) -> str:
    """``name path``, or ``name`` alone where it already shows the path (as a word of its own)."""
    return name if f" {path} " in f" {name} " else f"{name} {path}"


def _named(items: Named, default: str) -> list[tuple[str, Path]]:
    """(name, path) pairs of a mapping or of an iterable of paths and pairs; None paths left out."""
    pairs = items.items() if isinstance(items, Mapping) else (
        item if isinstance(item, tuple) else (default, item) for item in items)
    return [(name, Path(path)) for name, path in pairs if path is not None and str(path) != ""]


def _status(path: PathLike) -> os.stat_result | None:
    """``os.stat`` of the file a path names, or None where there is none (yet).

    A path that does not exist as spelled may still name an existing file once its folders are
    made: ``out/new/../../in/image.tif`` with ``out/new`` not there yet is ``in/image.tif`` as soon
    as a run creates ``out/new``. Its resolved path (links followed, ``..`` taken against the folders
    as they will be) is looked up too. Other errors (no permission to look) propagate."""
    try:
        return os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        pass
    try:
        return os.stat(Path(path).resolve())
    except (FileNotFoundError, NotADirectoryError, RuntimeError):  # RuntimeError: a loop of links
        return None


def file_identity(path: PathLike) -> tuple:
    """What makes a file the same file: ``("inode", st_dev, st_ino)`` of an existing file (through
    symbolic links, and through folders a run has not made yet, :func:`_status`), else
    ``("path", resolved path)``."""
    try:
        status = _status(path)
    except OSError:  # no permission to look: the spelling is all there is
        return ("path", Path(os.path.abspath(path)))
    if status is None:
        return ("path", Path(path).resolve())
    return ("inode", status.st_dev, status.st_ino)


def same_file(a: PathLike, b: PathLike) -> bool:
    """Whether two paths are the same file (:func:`file_identity`)."""
    return file_identity(a) == file_identity(b)


_KINDS = ((stat.S_ISDIR, "directory"), (stat.S_ISCHR, "character device"), (stat.S_ISBLK, "block device"),
          (stat.S_ISFIFO, "FIFO"), (stat.S_ISSOCK, "socket"))


def _not_regular(path: Path) -> str | None:
    """What an existing path is when it is no regular file ("directory", ...); None otherwise."""
    try:
        status = _status(path)
    except OSError:
        return None
    if status is None or stat.S_ISREG(status.st_mode):
        return None
    return next((kind for test, kind in _KINDS if test(status.st_mode)), "special file")


def sidecar_paths(path: PathLike) -> list[Path]:
    """The files GDAL may read or write beside a raster ``path``: ``NAME.hdr`` and ``NAME.ext.hdr``
    (an ENVI header; GDAL looks for both), ``NAME.ext.aux.xml`` (PAM: tags, statistics, band
    names), ``NAME.ext.ovr`` (overviews) and ``NAME.ext.msk`` (a mask)."""
    path = Path(path)
    found = [path.with_suffix(".hdr")] if path.suffix and path.suffix.lower() != ".hdr" else []
    found += [Path(f"{path}{suffix}") for suffix in (".hdr", ".aux.xml", ".ovr", ".msk")]
    return list(dict.fromkeys(found))


def _with_sidecars(inputs: list[tuple[str, Path]]) -> list[tuple[str, Path, tuple[str, Path] | None]]:
    """The inputs and every sidecar of each (GDAL reads them with the input), existing or not: the
    name, the path and, for a sidecar not there (yet), the (name, path) of its input."""
    found: list[tuple[str, Path, tuple[str, Path] | None]] = []
    for name, path in inputs:
        found.append((name, path, None))
        for sidecar in sidecar_paths(path):
            if os.path.lexists(sidecar):
                found.append((f"{name} sidecar", sidecar, None))
            elif not (_self_described(path) and sidecar.suffix.lower() == ".hdr"):  # GDAL reads no .hdr with it
                found.append((f"{name} sidecar", sidecar, (name, path)))
    return found


#: Formats GDAL identifies by their own header, never by an ENVI ``.hdr`` beside them (by name).
_SELF_DESCRIBED = (".tif", ".tiff", ".vrt", ".jp2", ".nc", ".h5", ".he5", ".hdf", ".png", ".jpg")


def _self_described(path: Path) -> bool:
    """A raster whose format GDAL knows from the file itself (a GeoTIFF, VRT, JPEG 2000, netCDF,
    HDF5, ...: :data:`_SELF_DESCRIBED`), so that no ENVI ``.hdr`` is ever read with it."""
    return path.suffix.lower() in _SELF_DESCRIBED


def check_outputs(outputs: Named, inputs: Named = ()) -> None:
    """Refuse outputs that are not regular files, that are an input, or that are another output.

    Parameters
    ----------
    outputs : mapping of name to path, or iterable of paths or (name, path) pairs
        What the command writes; the name is how messages call it (an option ``-o``, a config key
        ``outputs.report``; a name that shows the path is used as it is). None paths are skipped.
    inputs : mapping or iterable, as ``outputs``
        What the command reads; the sidecars of each (:func:`sidecar_paths`) are inputs too,
        existing or not (an output there would become the input's sidecar).

    Raises
    ------
    OutputError
        An output is a directory, device, FIFO or socket.
    InputOverwriteError
        An output is the same file as an input (an :class:`~brdfcorr.errors.InputError`), or
        (:class:`SidecarClashError`) a sidecar GDAL would read with an input.
    SameOutputError
        Two outputs are the same file (an :class:`~brdfcorr.errors.OutputError`).
    """
    read = [(name, path, file_identity(path), owner) for name, path, owner in _with_sidecars(_named(inputs, "input"))]
    written = []
    for name, path in _named(outputs, "output"):
        kind = _not_regular(path)
        if kind is not None:
            raise OutputError(f"{_describe(name, path)} is a {kind}, not a regular file; outputs are written "
                              "as regular files only")
        identity = file_identity(path)
        for input_name, input_path, input_identity, owner in read:
            if identity == input_identity and owner is not None:
                raise SidecarClashError(name, path, *owner, input_path)
            if identity == input_identity:
                raise InputOverwriteError(name, path, input_name, input_path)
        for other_name, other_path, other_identity in written:
            if identity == other_identity:
                raise SameOutputError(other_name, other_path, name, path)
        written.append((name, path, identity))


def check_format(path: str | os.PathLike, driver: str, what: str = "output") -> None:
    """Refuse an output whose file name extension does not belong to its format (:data:`EXTENSIONS`):
    ``out.img`` written as a GeoTIFF, or ``out.tif`` as ENVI, would mislead every reader.

    Raises
    ------
    InputError
        An unknown format, or an extension of another format.
    """
    if driver not in EXTENSIONS:
        raise InputError(f"unknown output format {driver!r}; choose one of {', '.join(FORMATS)}")
    suffix = Path(path).suffix.lower()
    if suffix not in EXTENSIONS[driver]:
        allowed = ", ".join(extension or "no extension" for extension in EXTENSIONS[driver])
        raise InputError(f"{what} {path}: extension {suffix or '(none)'} does not fit format {driver} "
                         f"(use {allowed})")


def refuse_existing(targets: Iterable[PathLike | None]) -> None:
    """Raise :class:`OutputError` for the first target that exists (a command run without
    ``--overwrite`` never replaces a file). None targets are skipped."""
    for target in targets:
        if target is not None and Path(target).exists():
            raise OutputError(f"output {target} exists; give --overwrite to replace it")


def update_target(output: PathLike, overwrite: bool, *, name: str = "-o", inputs: Named = ()) -> Path:
    """Where a command that adds to an existing file (a parameter table: ``fit -o``, ``materials
    -o``, ``coefficients -o``) writes: the rules of every output (:func:`check_outputs` against
    ``inputs``), an existing file only with ``overwrite`` (:func:`refuse_existing`), and a symbolic
    link's target, so that the link stays a link (the file it points to is rewritten, atomically).

    Raises
    ------
    OutputError
        ``output`` exists and ``overwrite`` is false; it is a symbolic link to no file (or a loop),
        or no regular file (:func:`check_outputs`).
    InputOverwriteError
        ``output`` is one of ``inputs`` (:func:`check_outputs`).
    """
    output = Path(output)
    check_outputs({name: output}, inputs)
    if not overwrite:
        refuse_existing([output])
    if not output.is_symlink():
        return output
    try:
        return output.resolve(strict=True)
    except (OSError, RuntimeError):  # a link to nothing, or a loop of links
        raise OutputError(f"{_describe(name, output)} is a symbolic link to no file; give the file's own "
                          "path") from None


def remove_partials(target: PathLike) -> list[Path]:
    """Remove what an interrupted write left beside ``target``: the temporary files
    ``.NAME.XXXXXXXX.partial`` of :func:`brdfcorr.io.files.atomic_path` (and ``.partial.gtiff`` of
    COG writes, ``.partial.hdr`` and ``.partial.aux.xml`` of ENVI writes). Returns the removed paths."""
    target = Path(target)
    pattern = re.compile(re.escape(f".{target.name}.") + r"[A-Za-z0-9_]+\.partial(\.gtiff|\.hdr|\.aux\.xml)?")
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(target.parent):
            if pattern.fullmatch(entry.name) and entry.is_file(follow_symlinks=False):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(entry.path)
                    removed.append(Path(entry.path))
    return removed


def envi_header_path(path: str | os.PathLike) -> Path:
    """The header GDAL writes beside an ENVI data file: ``out.img`` -> ``out.hdr``."""
    return Path(path).with_suffix(".hdr")


def stale_sidecars(target: str | os.PathLike, envi: bool = False) -> list[Path]:
    """The files GDAL reads with a raster ``target`` that writing it does not replace: its
    overviews (``.ovr``) and mask (``.msk``), and beside an ENVI data file the header
    ``NAME.ext.hdr``, which GDAL prefers to the ``NAME.hdr`` written (:func:`envi_header_path`).
    Left from an earlier file, they were read with the new one: its old overviews, half its pixels
    masked, its values read with another header (0.6 off) and no CRS."""
    second_header = envi and Path(f"{target}.hdr") != envi_header_path(target)  # not for an output "NAME"
    return [Path(f"{target}{suffix}") for suffix in (".ovr", ".msk", *((".hdr",) if second_header else ()))]


def raster_files(target: str | os.PathLike | None, envi: bool = False) -> list[Path]:
    """Every file of a raster output that must not exist before it is written without
    ``--overwrite`` (:func:`refuse_existing`): the raster, an ENVI output's header and ``.aux.xml``
    (another data file's header, ``NAME.hdr`` of ``NAME.bsq``, was replaced), and its
    :func:`stale_sidecars`; none for None."""
    if target is None:
        return []
    sidecars = [final for _, final in envi_sidecars(target, target)] if envi else []
    return [Path(target), *sidecars, *stale_sidecars(target, envi)]


def envi_sidecars(temporary: str | os.PathLike, target: str | os.PathLike) -> list[tuple[Path, Path]]:
    """The header and ``.aux.xml`` GDAL writes beside an ENVI data file at ``temporary``
    (``SUFFIX=ADD``: ``temporary.hdr``) and the names they get beside ``target``: its header
    ``NAME.hdr`` (:func:`envi_header_path`) and ``NAME.ext.aux.xml``."""
    return [(Path(f"{temporary}.hdr"), envi_header_path(target)),
            (Path(f"{temporary}.aux.xml"), Path(f"{target}.aux.xml"))]
