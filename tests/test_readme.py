"""Every command in the shell examples of the README and of docs/ runs (the docs must stay true).

The commands are taken from each page's ```bash blocks in order (``make`` targets excepted: they
build the environment this test runs in) and run with the package's ``brdfcorr`` on the PATH, in a
scratch directory that links the repository's ``configs/`` and ``examples/``: the README's first,
then each page of ``docs/`` in a copy of what the README's commands made (``demo_output/``), as a
reader who followed the README would have it. Pages are separate tests, so they run in parallel.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def page_commands(page: Path) -> list[str]:
    """The commands of a page's ```bash blocks, in order (``make`` and ``export`` lines excepted)."""
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", page.read_text(), flags=re.S):
        for command in block.replace("\\\n", " ").splitlines():
            command = command.split("  #")[0].strip()
            if command and not command.startswith(("make ", "export ")):
                commands.append(command)
    return commands


def run_commands(commands: list[str], directory: Path) -> None:
    """Run commands in order in ``directory`` (linking the repository's configs/ and examples/)."""
    for name in ("configs", "examples"):
        if not (directory / name).exists():
            (directory / name).symlink_to(ROOT / name)
    environment = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    for command in commands:
        result = subprocess.run(command, shell=True, cwd=directory, env=environment, capture_output=True, text=True,
                                timeout=300)
        assert result.returncode == 0, f"{command}\n{result.stdout}\n{result.stderr}"


@pytest.fixture(scope="session")
def readme_directory(tmp_path_factory) -> Path:
    """A directory in which the README's commands have run: its ``demo_output/`` is what the docs'
    commands start from, as a reader's would."""
    directory = tmp_path_factory.mktemp("readme")
    run_commands(page_commands(ROOT / "README.md"), directory)
    return directory


def test_readme_has_the_two_quick_start_commands():
    text = (ROOT / "README.md").read_text()
    assert "make demo" in text and "make test" in text
    assert len(page_commands(ROOT / "README.md")) >= 15


@pytest.mark.parametrize("page", [page.name for page in PAGES if page_commands(page)])
def test_every_command_of_a_page_runs(page, request, tmp_path):
    if page == "README.md":
        request.getfixturevalue("readme_directory")  # runs the README's commands and checks each
        return
    commands = page_commands(ROOT / "docs" / page)
    if any("demo_output" in command for command in commands):  # a copy of the README's results
        shutil.copytree(request.getfixturevalue("readme_directory") / "demo_output", tmp_path / "demo_output")
    run_commands(commands, tmp_path)


def test_every_python_example_runs():
    blocks = [block for page in PAGES for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)]
    assert blocks
    for block in blocks:
        exec(compile(block, "<docs>", "exec"), {})


def test_every_relative_link_resolves_and_nothing_points_outside_the_repository():
    for page in PAGES:
        text = page.read_text()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" in target:
                continue
            assert (page.parent / target).resolve().exists(), f"{page.name}: link {target} does not resolve"
    for path in [*PAGES, *(ROOT / "configs").glob("*.yaml"), ROOT / "examples" / "xarray_api.ipynb"]:
        assert "../shared" not in path.read_text() and "DESIGN.md" not in path.read_text(), path
