"""Small file helpers: outputs appear complete or not at all; YAML documents are read with bounds.

A YAML document (parameter table, chain config, lookup table, ``--set`` value) is read by
:func:`read_document` (a regular file of at most :data:`MAX_DOCUMENT_BYTES`, UTF-8) and parsed by
:func:`parse_yaml`: plain data only (``safe_load``'s constructors), one document, duplicate mapping
keys refused, nesting and alias expansion bounded (:data:`MAX_DEPTH`, :data:`MAX_ALIAS_NODES`).
Every problem is one error naming the source, never a hang, a gigabyte or a traceback.
"""

from __future__ import annotations

import contextlib
import errno
import gc
import hashlib
import os
import signal
import stat
import tempfile
import threading
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterable, Iterator
from pathlib import Path

import yaml
from yaml.composer import Composer, ComposerError
from yaml.constructor import ConstructorError, SafeConstructor
from yaml.events import AliasEvent
from yaml.nodes import MappingNode, ScalarNode
from yaml.resolver import Resolver

from brdfcorr.errors import OutputError

try:  # libyaml's scanner and parser (C): 4x faster than PyYAML's on a large table
    from yaml._yaml import CParser as _Parser

    _SyntaxChecker: type | None = _Parser
except ImportError:  # pragma: no cover (PyYAML built without libyaml)
    _SyntaxChecker = None
    from yaml.parser import Parser
    from yaml.reader import Reader
    from yaml.scanner import Scanner

    class _Parser(Reader, Scanner, Parser):  # type: ignore[no-redef]
        def __init__(self, stream):
            Reader.__init__(self, stream)
            Scanner.__init__(self)
            Parser.__init__(self)


__all__ = ["atomic_path", "atomic_paths", "temporary_beside", "content_digest", "sync_file", "write_cause",
           "DISK_CAUSES", "read_document", "read_regular", "parse_yaml", "MAX_DOCUMENT_BYTES", "MAX_ALIAS_NODES",
           "MAX_DEPTH"]

#: Largest YAML document brdfcorr reads [bytes]. A table of 20 000 classes is about 2 MB; a bigger
#: file is a mistake (an image given as a table) and would take minutes to parse.
MAX_DOCUMENT_BYTES = 10_000_000
#: Most nodes the aliases (``*name``) of a YAML document may add, counted as if every alias were
#: written out: a few hundred bytes of nested aliases (an "alias bomb") expand to 10^9 values.
#: Sharing a parameter list or a wavelength list between 20 000 classes stays far below.
MAX_ALIAS_NODES = 1_000_000
#: Deepest nesting of a YAML document (tables and configs nest 5 levels); also keeps the
#: composer's recursion far from Python's limit.
MAX_DEPTH = 100
_MERGE_TAG = "tag:yaml.org,2002:merge"


@contextlib.contextmanager
def interrupts_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM held back for the ``with`` block and delivered at its end, to the handlers
    they had (in the main thread, where Python runs its signal handlers; elsewhere nothing is held).

    Around the making of a temporary file and the recording of its name (:func:`atomic_path`,
    :mod:`brdfcorr.io.writer`): an interrupt between the two would leave a file that no cleanup
    knows; held back, it arrives where the name is known and the cleanup removes the file. The
    handlers are swapped, not the signals blocked: a signal sent to the process may be taken by
    any of its threads, so a mask of this thread alone would not hold it.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    numbers = (signal.SIGINT, signal.SIGTERM)
    caught: list[int] = []
    previous = {number: signal.signal(number, lambda number, frame: caught.append(number)) for number in numbers}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, signal.SIG_DFL if handler is None else handler)
        if caught:
            signal.raise_signal(caught[0])  # to its own handler again: KeyboardInterrupt, the CLI's exit


def temporary_beside(target: str | os.PathLike, suffix: str = ".partial") -> Path:
    """Create an empty temporary file ``.NAME.XXXXXXXX{suffix}`` beside ``target`` (the names
    :func:`brdfcorr.io.paths.remove_partials` knows), with the mode a plain ``open()`` would give
    (``mkstemp`` makes it private, 0600)."""
    target = Path(target)
    handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix, dir=target.parent or ".")
    os.close(handle)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temporary, 0o666 & ~umask)
    return Path(temporary)


def sync_file(path: str | os.PathLike) -> None:
    """Flush a written file to its device (``fsync``): a full disk or a failing device that the
    kernel reports only at write-back time is an ``OSError`` here, before the file is renamed."""
    descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


#: How :func:`write_cause` begins when the cause is the file size limit or a full device.
DISK_CAUSES = ("File too large", "No space left on device")


def write_cause(error: BaseException | None, paths=(), detail: str = "") -> str:
    """Why a write failed, in words: the OS reason of an ``OSError`` (permissions, ...), but the file
    size limit (``ulimit -f``, RLIMIT_FSIZE) when the error is EFBIG or, without an OS reason, a
    file of ``paths`` reached it; a full device (with the bytes left) for ENOSPC/EDQUOT or, without
    an OS reason, when less than 1 MiB is left where ``paths`` are; else ``detail`` (GDAL's message).

    GDAL reports a failed write of a TIFF tile or an ENVI line without the OS reason, so the limit
    and the free space are looked at here, before the temporary files are removed.
    """
    paths = [Path(path) for path in paths]
    number = getattr(error, "errno", None)
    if isinstance(error, OSError) and error.strerror and number not in (errno.EFBIG, errno.ENOSPC, errno.EDQUOT):
        return error.strerror + (f": {error.filename}" if error.filename else "")  # the OS said why
    limit = _file_size_limit()
    if limit is not None and (number == errno.EFBIG or any(_size(path) >= limit for path in paths)):
        return f"File too large: the file size limit (ulimit -f) of {limit} bytes was reached"
    if number == errno.EFBIG:
        return "File too large: larger than the file system allows"
    free = min((_free_bytes(path.parent) for path in paths), default=None)
    if number in (errno.ENOSPC, errno.EDQUOT) or (free is not None and free < 2**20):
        where = f" ({free} bytes left on the device of {paths[0].parent})" if free is not None else ""
        return f"No space left on device{where}"
    return detail or (str(error) if error is not None else "unknown reason")


def _file_size_limit() -> int | None:
    try:
        import resource  # POSIX only
    except ImportError:  # pragma: no cover (Windows)
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return -1


def _free_bytes(folder: Path) -> int | None:
    try:
        status = os.statvfs(folder)
    except (OSError, AttributeError):  # no statvfs on Windows
        return None
    return status.f_bavail * status.f_frsize


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike):
    """Yield a temporary path beside ``target``; flush it and rename it onto ``target`` only on success.

    A crash or an exception inside the block leaves no file at ``target`` (and removes the
    temporary one), so a partial output never looks complete. An ``OSError`` while writing,
    flushing or renaming (a full disk, the file size limit, permissions) becomes one
    :class:`~brdfcorr.errors.OutputError` naming ``target`` and the cause (:func:`write_cause`).
    """
    target = Path(target)
    temporary = None
    try:
        try:
            with interrupts_held():  # a Ctrl-C while the file is made arrives once ``temporary`` names it
                temporary = temporary_beside(target)
        except OSError as error:
            raise OutputError(f"cannot write {target}: {write_cause(error, [target])}") from None
        yield temporary
        sync_file(temporary)
        os.replace(temporary, target)
    except OutputError:  # already one message (an OSError too)
        raise
    except OSError as error:
        cause = write_cause(error, [temporary])
        raise OutputError(f"cannot write {target}: {cause}; nothing was written") from None
    finally:
        if temporary is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)


@contextlib.contextmanager
def atomic_paths(targets: Iterable[str | os.PathLike]) -> Iterator[dict[Path, Path]]:
    """Yield a temporary path beside each of several ``targets`` ({target: temporary}); rename them
    all onto their targets only when the block succeeds: the outputs of one command appear together
    or not at all (a table beside a report and figures that failed to write would look finished).

    Every target's folder is made and its temporary file created before the block runs, so a
    target that cannot be written (a folder that is a file, no permission) fails before anything
    is. An exception in the block, or while flushing or renaming, leaves the targets as they were
    (a file already at a target, replaced with ``--overwrite``, is moved aside before the renames
    and put back if one fails: :func:`_rename_all`) and no temporary file. An ``OSError``
    becomes one :class:`~brdfcorr.errors.OutputError` naming the target(s) and the cause
    (:func:`write_cause`), as in :func:`atomic_path`.
    """
    temporaries: dict[Path, Path] = {}
    try:
        for target in map(Path, dict.fromkeys(targets)):
            try:
                target.parent.mkdir(parents=True, exist_ok=True)
                with interrupts_held():  # a Ctrl-C while the file is made arrives once ``temporaries`` names it
                    temporaries[target] = temporary_beside(target)
            except OSError as error:
                cause = write_cause(error, [target])
                raise OutputError(f"cannot write {target}: {cause}; nothing was written") from None
        yield dict(temporaries)
        for temporary in temporaries.values():
            sync_file(temporary)
        with interrupts_held():  # a Ctrl-C between moving the old files aside and putting them back waits
            _rename_all(temporaries)
    except OutputError:  # already one message
        raise
    except OSError as error:
        cause = write_cause(error, list(temporaries.values()))
        raise OutputError(f"cannot write {', '.join(map(str, temporaries))}: {cause}; nothing was written") from None
    finally:
        for temporary in temporaries.values():
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)


def _rename_all(temporaries: dict[Path, Path]) -> None:
    """Rename each temporary onto its target, the files already at the targets moved aside first
    (:func:`_set_aside`); where a rename fails, the targets renamed are removed, the old files put
    back and the error raised; once all are renamed, the old files are removed. An old output is
    thus lost only when every new one is in place (a backup that cannot be put back stays beside
    its target as ``.NAME.XXXXXXXX.backup``)."""
    backups: dict[Path, Path] = {}
    renamed = []
    try:
        for target in temporaries:
            backup = _set_aside(target)
            if backup is not None:
                backups[target] = backup
        for target, temporary in temporaries.items():
            os.replace(temporary, target)
            renamed.append(target)
    except OSError:
        for target in renamed:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(target)
        for target, backup in backups.items():
            with contextlib.suppress(OSError):
                os.replace(backup, target)
        raise
    for backup in backups.values():
        with contextlib.suppress(FileNotFoundError):
            os.unlink(backup)


def _set_aside(target: Path) -> Path | None:
    """Move a file (or link) at ``target`` to a new backup name beside it
    (:func:`temporary_beside`, ``.backup``: not a temporary that
    :func:`brdfcorr.io.paths.remove_partials` removes); its path, or None where there is none."""
    if not os.path.lexists(target):
        return None
    backup = temporary_beside(target, ".backup")
    try:
        os.replace(target, backup)
    except OSError:
        os.unlink(backup)  # still the empty file made for the name
        raise
    return backup


_FILE_KINDS = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFCHR: "a character device",
               stat.S_IFBLK: "a block device", stat.S_IFSOCK: "a socket"}


#: Files up to this size are hashed whole by :func:`content_digest` [bytes] (about 0.1 s).
FULL_HASH_BYTES = 64 * 2**20
#: Larger files: their first and last :data:`EDGE_BYTES` (headers, TIFF directories, ENVI
#: trailers) and :data:`SAMPLES` pieces of :data:`SAMPLE_BYTES` spread evenly between.
EDGE_BYTES, SAMPLES, SAMPLE_BYTES = 2**20, 64, 64 * 2**10


def content_digest(path: str | os.PathLike) -> str:
    """A SHA-256 of a file's content: the whole file up to :data:`FULL_HASH_BYTES`, else its header,
    its end and an even sample of its data (about 6 MB, read in milliseconds from any size).

    What a resumed run compares besides a file's size and modification time: a file edited in place
    that kept both (``touch -r``, a copy with ``cp -p``) is caught where the edit lies in what is
    hashed, always for a small file and for any header of a large one.
    """
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if size <= FULL_HASH_BYTES:
            for piece in iter(lambda: handle.read(2**20), b""):
                digest.update(piece)
            return digest.hexdigest()
        step = (size - 2 * EDGE_BYTES) // SAMPLES
        offsets = [(0, EDGE_BYTES), *((EDGE_BYTES + index * step, SAMPLE_BYTES) for index in range(SAMPLES)),
                   (size - EDGE_BYTES, EDGE_BYTES)]
        for offset, length in offsets:
            handle.seek(offset)
            digest.update(handle.read(length))
    return digest.hexdigest()


def read_document(
    path: str | os.PathLike, what: str, error: type[Exception], *, max_bytes: int = MAX_DOCUMENT_BYTES,
) -> str:
    """The text of a YAML document file: a regular file of at most ``max_bytes``, UTF-8.

    Read by :func:`read_regular` (a FIFO or a device is refused, never waited on); a binary,
    Latin-1 or UTF-16 file is no document: each is one ``error`` (a
    :class:`~brdfcorr.errors.BrdfcorrError` subclass), ``cannot read {what} {path}: {reason}``.
    A UTF-8 byte-order mark is dropped.
    """
    path = Path(path)
    data = read_regular(path, what, error, max_bytes=max_bytes)
    return _decode(data, lambda reason: error(f"cannot read {what} {path}: {reason}"))


def read_xml(path: str | os.PathLike, what: str, error: type[Exception]):
    """The root element of a product's XML metadata (:func:`read_regular`: a regular file only,
    a FIFO would block); a file that is no XML is one ``error``, ``{path}: cannot read {what}
    ({reason})``."""
    data = read_regular(path, what, error)
    try:
        return ElementTree.fromstring(data)
    except ElementTree.ParseError as problem:
        raise error(f"{path}: cannot read {what} ({problem})") from problem


def read_regular(
    path: str | os.PathLike, what: str, error: type[Exception], *, max_bytes: int = MAX_DOCUMENT_BYTES,
) -> bytes:
    """The bytes of a small metadata file (a YAML document, a product's XML or text metadata): a
    regular file of at most ``max_bytes``.

    A FIFO or a device (``/dev/urandom``) would block or never end, a directory is no file: each is
    one ``error`` (a :class:`~brdfcorr.errors.BrdfcorrError` subclass), ``cannot read {what} {path}:
    {reason}``. The file is opened without blocking and checked with ``fstat`` on the open
    descriptor, so nothing can swap it between the check and the read.
    """
    path = Path(path)

    def refuse(reason: str) -> Exception:
        return error(f"cannot read {what} {path}: {reason}")

    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        descriptor = os.open(path, flags)  # O_NONBLOCK: opening a FIFO does not wait for a writer
    except OSError as problem:
        raise refuse(problem.strerror or str(problem)) from None
    too_big = refuse(f"larger than {max_bytes / 1e6:g} MB; is it the right file?")
    try:
        status = os.fstat(descriptor)
        if stat.S_ISDIR(status.st_mode):
            raise refuse("Is a directory")
        if not stat.S_ISREG(status.st_mode):
            kind = _FILE_KINDS.get(stat.S_IFMT(status.st_mode), "a special file")
            raise refuse(f"not a regular file ({kind})")
        if status.st_size > max_bytes:
            raise too_big
        handle = open(descriptor, "rb", closefd=True)
    except BaseException:
        os.close(descriptor)
        raise
    with handle:
        try:
            data = handle.read(max_bytes + 1)  # the file may grow after fstat
        except OSError as problem:
            raise refuse(problem.strerror or str(problem)) from None
    if len(data) > max_bytes:
        raise too_big
    return data


def _decode(data: bytes, refuse) -> str:
    if data.startswith((b"\xff\xfe", b"\xfe\xff", b"\x00\x00\xfe\xff")):
        raise refuse("UTF-16 or UTF-32 text; save it as UTF-8")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise refuse(f"a binary file, not UTF-8 text (NUL byte at offset {nul})")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as problem:
        line = data.count(b"\n", 0, problem.start) + 1
        byte = data[problem.start]
        raise refuse(f"not UTF-8 text (byte 0x{byte:02x} on line {line}); save it as UTF-8") from None


def _shorten(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


class _BoundedComposer(Composer):
    """PyYAML's composer, bounding the nesting depth and the nodes that aliases add.

    The expanded size of a node (1 + the expanded sizes of its items, an alias counting as the
    whole node it names) is known when the node is complete; every alias adds the size of its
    node. An alias to a node still being composed makes the document recursive: refused.
    """

    def __init__(self):
        super().__init__()
        self._sizes: dict[int, int] = {}  # expanded size of each complete collection node, by id
        self._alias_nodes = 0
        self._depth = 0

    def _size(self, node) -> int:
        return 1 if isinstance(node, ScalarNode) else self._sizes[id(node)]

    def compose_node(self, parent, index):
        if self.check_event(AliasEvent):
            event = self.peek_event()
            node = super().compose_node(parent, index)
            if not isinstance(node, ScalarNode) and id(node) not in self._sizes:
                raise ComposerError(None, None, f"alias *{_shorten(event.anchor)} is inside the node it "
                                    "names (a recursive document)", event.start_mark)
            self._alias_nodes += self._size(node)
            if self._alias_nodes > MAX_ALIAS_NODES:
                raise ComposerError(None, None, f"its aliases expand to more than {MAX_ALIAS_NODES:,} "
                                    "values (an alias bomb?); write the repeated values out",
                                    event.start_mark)
            return node
        if self._depth >= MAX_DEPTH:
            raise ComposerError(None, None, f"nested more than {MAX_DEPTH} levels deep",
                                self.peek_event().start_mark)
        self._depth += 1
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if isinstance(node, MappingNode):
            self._sizes[id(node)] = 1 + sum(self._size(key) + self._size(value) for key, value in node.value)
        elif not isinstance(node, ScalarNode):
            self._sizes[id(node)] = 1 + sum(self._size(item) for item in node.value)
        return node


class _UniqueKeyConstructor(SafeConstructor):
    """``safe_load``'s constructors, refusing a mapping that repeats a key (YAML forbids it;
    PyYAML would keep the last value, so a class or a section could vanish unseen). Keys merged
    with ``<<`` may be overridden, as YAML's merge keys intend."""

    def __init__(self):
        super().__init__()
        self._checked: set[int] = set()

    def flatten_mapping(self, node):
        # Runs on every mapping before it is constructed or merged (and modified by merging).
        if id(node) not in self._checked:
            self._checked.add(id(node))
            seen: dict[object, ScalarNode] = {}
            for key_node, _ in node.value:
                if not isinstance(key_node, ScalarNode) or key_node.tag == _MERGE_TAG:
                    continue  # a collection as a key is refused as unhashable by the constructor
                key = self.construct_object(key_node)
                try:
                    first = seen.setdefault(key, key_node)
                except TypeError:
                    continue
                if first is not key_node:
                    raise ConstructorError(
                        None, None, f"duplicate key {_shorten(repr(key))} (first on line "
                        f"{first.start_mark.line + 1}); a mapping may have each key once",
                        key_node.start_mark)
        super().flatten_mapping(node)

    def construct_undefined(self, node):
        tag = node.tag.replace("tag:yaml.org,2002:", "!!")
        raise ConstructorError(None, None, f"the tag {_shorten(tag)} is not allowed: a table or config holds "
                               "plain data only (numbers, text, lists, mappings)", node.start_mark)


_UniqueKeyConstructor.add_constructor(None, _UniqueKeyConstructor.construct_undefined)


class _Loader(_BoundedComposer, _Parser, _UniqueKeyConstructor, Resolver):
    """libyaml's parser, the bounded composer, the safe constructors without duplicate keys."""

    def __init__(self, stream):
        _Parser.__init__(self, stream)
        _BoundedComposer.__init__(self)
        _UniqueKeyConstructor.__init__(self)
        Resolver.__init__(self)


@contextlib.contextmanager
def _collector_paused():
    """Pause the cyclic garbage collector while a document is built: a large table makes ~10^6
    objects and no reference cycles, and the collections that many allocations trigger triple
    the time (measured: 20 000 classes, 2.2 MB: 6 s, 2 s paused)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _check_syntax(text: str) -> None:
    """Run libyaml's scanner and parser over the whole text in C, building no Python objects.

    A syntax error anywhere in a 10 MB document is found in about 0.4 s this way, before the
    composer builds nodes in Python (about 3 s per MB); libyaml also bounds the nesting (1000).
    """
    if _SyntaxChecker is not None:
        _SyntaxChecker(text).raw_parse()


def parse_yaml(text: str, source: str, error: type[Exception]) -> object:
    """Parse one YAML document with ``yaml.safe_load``'s constructors (plain data only: no Python
    objects, no code), refusing duplicate keys, recursive aliases, alias expansion beyond
    :data:`MAX_ALIAS_NODES` values and nesting beyond :data:`MAX_DEPTH` levels.

    Every problem becomes one ``error`` (a :class:`~brdfcorr.errors.BrdfcorrError` subclass) whose
    message names ``source`` and, where the parser knows it, the line and column.
    """
    try:
        loader = _Loader(text)
    except (ValueError, TypeError) as problem:  # text libyaml cannot take (a lone surrogate)
        raise error(f"{source}: not valid YAML: {_shorten(' '.join(str(problem).split()), 200)}") from None
    try:
        with _collector_paused():
            _check_syntax(text)
            node = loader.get_single_node()
            return loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as found:
        problem = found
        mark = getattr(problem, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        reason = getattr(problem, "problem", None) or " ".join(str(problem).split())
        raise error(f"{source}: not valid YAML{where}: {_shorten(reason, 200)}") from None
    except (ValueError, TypeError, RecursionError) as problem:
        # PyYAML's constructors raise these for a timestamp that is no date (2001-02-30), a
        # mapping key that cannot be hashed, or an integer of more than 4300 digits.
        raise error(f"{source}: not valid YAML: {_shorten(' '.join(str(problem).split()), 200)}") from None
    finally:
        loader.dispose()
