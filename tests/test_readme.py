"""Every command in the shell examples of the README and of docs/ runs (the docs must stay true).

The commands are taken from the ```bash blocks in order, the README's first and then the pages of
``docs/`` by name (``make`` targets excepted: they build the environment this test runs in), and
run with the package's ``brdfcorr`` on the PATH, in one scratch directory that links the
repository's ``configs/`` and ``examples/``.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]


def readme_commands() -> list[str]:
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    blocks = [block for page in pages for block in re.findall(r"```bash\n(.*?)```", page.read_text(), flags=re.S)]
    commands = []
    for block in blocks:
        for command in block.replace("\\\n", " ").splitlines():
            command = command.split("  #")[0].strip()
            if command and not command.startswith(("make ", "export ")):
                commands.append(command)
    return commands


def test_readme_has_the_two_quick_start_commands():
    text = (ROOT / "README.md").read_text()
    assert "make demo" in text and "make test" in text


def test_every_readme_command_runs(tmp_path):
    for name in ("configs", "examples"):
        (tmp_path / name).symlink_to(ROOT / name)
    environment = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    commands = readme_commands()
    assert len(commands) >= 15
    for command in commands:
        result = subprocess.run(
            command, shell=True, cwd=tmp_path, env=environment, capture_output=True, text=True,
            timeout=300,
        )
        assert result.returncode == 0, f"{command}\n{result.stdout}\n{result.stderr}"


def test_every_python_example_runs():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    blocks = [block for page in pages for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)]
    assert blocks
    for block in blocks:
        exec(compile(block, "<docs>", "exec"), {})


def test_every_relative_link_resolves_and_nothing_points_outside_the_repository():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for page in pages:
        text = page.read_text()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" in target:
                continue
            assert (page.parent / target).resolve().exists(), f"{page.name}: link {target} does not resolve"
    for path in [*pages, *(ROOT / "configs").glob("*.yaml"), ROOT / "examples" / "xarray_api.ipynb"]:
        assert "../shared" not in path.read_text() and "DESIGN.md" not in path.read_text(), path
