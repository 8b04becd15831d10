"""Every command in the shell examples of the README and of docs/ runs (the docs must stay true).

The commands are taken from each page's ```bash blocks in order (``make`` targets excepted: they
build the environment this test runs in) and run with the package's ``brdfcorr`` on the PATH, in a
scratch directory that links the repository's ``configs/`` and ``examples/`` (``brdfcorr`` and
``python script.py`` commands in processes forked from one that has imported the package:
:func:`run_commands`).

A page's commands fall into groups (:data:`GROUPS`): a group is the commands from its first one up
to the next group's first, run in order in a directory of its own that starts as a copy of what the
groups it needs made. A group that needed a file made by a group it does not name would fail (the
file is not in its copy), so a wrong split fails the test; it never hides a failure. Each group is
one test, so groups that do not depend on each other run in parallel (pytest-xdist), and each is run
once per session for all workers (:func:`_build`: a lock file in the session's shared temporary
folder), however many other groups start from its outputs.

The docs' pages start where a reader who followed the README would: from a copy of what all of the
README's commands made (``demo_output/``). A command of a page that repeats a README command
verbatim and names no file (``brdfcorr models``) is not run twice: the README's run of it stands for
it (its output cannot differ).
"""

from __future__ import annotations

import fcntl
import glob
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import _forked
import pytest

ROOT = Path(__file__).parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: Where a page's commands split into groups that run apart: for each group, the start of its first
#: command, its name and the groups it starts from ("page:name"; "README.md" is every README group).
#: A page not listed is one group named "all", which starts from the README's outputs if one of its
#: commands names demo_output/, else from an empty directory.
GROUPS = {
    "README.md": [
        ("brdfcorr models", "listings", ()),
        ("brdfcorr demo -o demo_output", "demo", ()),
        ("brdfcorr validate configs/*.yaml", "chain", ("README.md:demo",)),
        ("brdfcorr correct demo_output/", "correct", ("README.md:demo",)),
        ("brdfcorr fit-classes demo_output/", "fit-classes", ("README.md:demo",)),
        ("python examples/make_goniometer_csv.py", "goniometer", ("README.md:demo",)),
        ("brdfcorr analyze", "analyze", ("README.md:demo",)),
    ],
    "classmaps.md": [
        ("brdfcorr classes ndvi", "strata", ("README.md",)),
        ("python examples/make_landcover.py", "landcover", ("README.md",)),
    ],
    "parameter-tables.md": [
        ("brdfcorr materials roof_tile", "materials", ("README.md",)),
        ("printf", "material-classes", ("README.md",)),
        ("brdfcorr coefficients", "coefficients", ("README.md",)),
        ("brdfcorr classes ndvi", "prior", ("README.md",)),
    ],
    "sensors.md": [
        ("python examples/make_sensor_products.py", "products", ()),
        ("brdfcorr classes ndvi products/aviris-ng/", "aviris", ("sensors.md:products",)),
        ("brdfcorr classes ndvi products/neon/", "neon", ("sensors.md:products",)),
        ("brdfcorr classes ndvi products/emit/", "emit", ("sensors.md:products", "sensors.md:aviris")),
        ("python examples/nbar_products.py", "s2_l7", ()),
        ("brdfcorr nbar s2_l7/S2A", "sentinel2", ("sensors.md:s2_l7",)),
        ("brdfcorr nbar s2_l7/LE07", "landsat", ("sensors.md:s2_l7",)),
        ("brdfcorr nbar s2_l7/S2A_MSIL2A_20190425T132241_N0400_R038_T23LLF_20190425T164208.SAFE --factor-at nodes",
         "sentinel2-nodes", ("sensors.md:s2_l7",)),
    ],
}


class Group(NamedTuple):
    """Commands of one page that run in order in one directory, after copies of what ``needs`` made."""

    page: str
    commands: tuple[str, ...]
    needs: tuple[str, ...]


def page_commands(page: Path) -> list[str]:
    """The commands of a page's ```bash blocks, in order (``make`` and ``export`` lines excepted)."""
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", page.read_text(), flags=re.S):
        for command in block.replace("\\\n", " ").splitlines():
            command = command.split("  #")[0].strip()
            if command and not command.startswith(("make ", "export ")):
                commands.append(command)
    return commands


def page_groups(page: Path) -> dict[str, Group]:
    """The groups of a page's commands by "page:name", in page order (:data:`GROUPS`)."""
    commands = page_commands(page)
    readme = ("README.md",) if any("demo_output" in command for command in commands) else ()
    splits = GROUPS.get(page.name) or [(commands[0], "all", readme)]
    starts, position = [], 0
    for start, name, _ in splits:
        position = next((i for i in range(position, len(commands)) if commands[i].startswith(start)), None)
        assert position is not None, f"{page.name}: no command starts with {start!r} after the group before"
        starts.append(position)
    assert starts[0] == 0, f"{page.name}: the first group must start with the first command"
    ends = [*starts[1:], len(commands)]
    return {f"{page.name}:{name}": Group(page.name, tuple(commands[a:b]), needs)
            for (_, name, needs), a, b in zip(splits, starts, ends)}


ALL_GROUPS = {key: group for page in PAGES if page_commands(page) for key, group in page_groups(page).items()}
README_COMMANDS = {command: key for key, group in ALL_GROUPS.items() if group.page == "README.md"
                   for command in group.commands}
#: "README.md": every README group, the directory the docs start from.
ALL_GROUPS["README.md"] = Group("README.md", (), tuple(key for key in ALL_GROUPS if key.startswith("README.md:")))


#: Shell syntax beyond words and globs: such a command runs in a shell.
_SHELL_SYNTAX = re.compile(r"[|&;<>()$`\\\n]")


def _argv(command: str, directory: Path) -> list[str] | None:
    """The arguments of a ``brdfcorr ...`` or ``python script.py ...`` command with no shell syntax
    but globs, expanded as the shell would (sorted; a glob that matches nothing stays as written),
    else None (the command runs in a shell)."""
    if _SHELL_SYNTAX.search(command):
        return None
    words = shlex.split(command)
    if words[0] != "brdfcorr" and not (words[0] == "python" and len(words) > 1 and words[1].endswith(".py")):
        return None
    expanded = []
    for word in words:
        matches = sorted(glob.glob(word, root_dir=directory)) if glob.has_magic(word) else []
        expanded.extend(matches or [word])
    return expanded


def run_commands(commands, directory: Path) -> None:
    """Run commands in order in ``directory`` (linking the repository's configs/ and examples/).

    A ``brdfcorr`` or ``python script.py`` command without shell syntax runs in a process forked
    from a server that has imported the package (tests/_forked.py: the same console-script entry
    point, without 2 s of imports a command); any other runs in a shell.
    """
    for name in ("configs", "examples"):
        if not (directory / name).exists():
            (directory / name).symlink_to(ROOT / name)
    environment = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    for command in commands:
        argv = _argv(command, directory)
        result = (_forked.run(argv, cwd=directory, env=environment, timeout=600) if argv is not None else
                  subprocess.run(command, shell=True, cwd=directory, env=environment, capture_output=True, text=True,
                                 timeout=600))
        assert result.returncode == 0, f"{command}\n{result.stdout}\n{result.stderr}"


def _copy_into(source: Path, target: Path) -> None:
    """Copy the files of ``source`` into ``target`` (the links to configs/ and examples/ excepted),
    skipping files that a copy of the same file already put there (same size and time)."""
    for folder, _, files in os.walk(source):
        relative = Path(folder).relative_to(source)
        if relative.parts[:1] in (("configs",), ("examples",)):
            continue
        (target / relative).mkdir(parents=True, exist_ok=True)
        for name in files:
            path, copy = Path(folder) / name, target / relative / name
            if path.is_symlink() or (copy.exists() and (copy.stat().st_size, copy.stat().st_mtime_ns)
                                     == (path.stat().st_size, path.stat().st_mtime_ns)):
                continue
            shutil.copy2(path, copy)


def _run_group(key: str, directory: Path, build) -> None:
    """Run a group's commands in ``directory`` after copying in what the groups it needs made."""
    group = ALL_GROUPS[key]
    built = _built_all(group.needs, build)
    for need in group.needs:
        _copy_into(built[need], directory)
    for command in group.commands:
        if group.page != "README.md" and command in README_COMMANDS and not re.search(r"/|>|-o\b", command):
            build(README_COMMANDS[command])
        else:
            run_commands([command], directory)


def _built_all(keys, build) -> dict[str, Path]:
    """The directories of the groups ``keys``: those no other worker is building are built first,
    then the others waited for, so that two workers build the groups they both need side by side
    instead of one waiting for the other (``build(key, wait=False)``: None while another holds it)."""
    built: dict[str, Path] = {}
    while len(built) < len(keys):
        for key in keys:
            if key not in built and (directory := build(key, wait=False)) is not None:
                built[key] = directory
        waiting = [key for key in keys if key not in built]
        if waiting:
            built[waiting[0]] = build(waiting[0])
    return built


def _build(root: Path, key: str, wait: bool = True) -> Path | None:
    """The directory in which group ``key`` ran, under ``root``: run by the first worker that asks,
    which holds a lock file meanwhile; the others wait for it (or, without ``wait``, get None while
    it runs) and reuse the directory (or its failure)."""
    name = key.replace(":", "-")
    directory, done, failed = root / name, root / f"{name}.done", root / f"{name}.failed"
    with open(root / f"{name}.lock", "a") as lock:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            return None
        if failed.exists():
            pytest.fail(f"{key} failed (in another test):\n{failed.read_text()}")
        if not done.exists():
            shutil.rmtree(directory, ignore_errors=True)
            directory.mkdir()
            try:
                _run_group(key, directory, lambda need, wait=True: _build(root, need, wait))
            except BaseException as error:
                failed.write_text(str(error))
                raise
            done.touch()
    return directory


def builder(tmp_path_factory):
    """``build(key)``: the directory in which group ``key`` ran, shared by the session's workers
    (the parent of a worker's temporary folder is the session's) and by the tests that check what a
    page's commands wrote (tests/workflow/test_sensor_examples.py)."""
    base = tmp_path_factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "doc-commands"
    root.mkdir(exist_ok=True)
    return lambda key, wait=True: _build(root, key, wait)


@pytest.fixture(scope="session")
def build(tmp_path_factory):
    """:func:`builder`'s ``build(key)``."""
    return builder(tmp_path_factory)


def test_readme_has_the_two_quick_start_commands():
    text = (ROOT / "README.md").read_text()
    assert "make demo" in text and "make test" in text
    assert len(page_commands(ROOT / "README.md")) >= 15


def test_groups_keep_every_command_once_and_in_order():
    for page in PAGES:
        groups = [group for group in ALL_GROUPS.values() if group.page == page.name and group.commands]
        assert [command for group in groups for command in group.commands] == page_commands(page), page.name
    assert "brdfcorr demo -o demo_output" in README_COMMANDS


#: The groups that need none first, so that a second worker has one to run while the first makes
#: what the others start from.
TESTED = sorted((key for key in ALL_GROUPS if ":" in key),
                key=lambda key: bool(ALL_GROUPS[key].needs))


@pytest.mark.parametrize("group", TESTED)
def test_every_command_of_a_page_runs(group, build):
    build(group)


#: Each ```python block of the pages by "page:number" (from 1): one test each, run in a namespace of
#: its own, so a block that needed another's names would fail.
PYTHON_BLOCKS = {f"{page.name}:{number}": block for page in PAGES
                 for number, block in enumerate(re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S), 1)}


def test_the_pages_have_python_examples():
    assert len(PYTHON_BLOCKS) >= 10 and "README.md:1" in PYTHON_BLOCKS


@pytest.mark.parametrize("key", PYTHON_BLOCKS)
def test_every_python_example_runs(key):
    exec(compile(PYTHON_BLOCKS[key], f"<{key}>", "exec"), {})


def test_every_relative_link_resolves_and_nothing_points_outside_the_repository():
    for page in PAGES:
        text = page.read_text()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" in target:
                continue
            assert (page.parent / target).resolve().exists(), f"{page.name}: link {target} does not resolve"
    for path in [*PAGES, *(ROOT / "configs").glob("*.yaml"), ROOT / "examples" / "xarray_api.ipynb"]:
        assert "../shared" not in path.read_text() and "DESIGN.md" not in path.read_text(), path
