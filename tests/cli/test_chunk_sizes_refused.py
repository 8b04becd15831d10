"""Chunk sizes are refused while parsing: ``--chunk`` (every command that has it), a chain's
``engine.chunk`` (in the file or by ``--set``) and the library's ``Engine`` refuse 0, negative sizes and
non-multiples of 16 (0 was a ZeroDivisionError, exit 1). Each refusal ends in exit code 2, exactly one
stderr line ``brdfcorr: error: ...`` naming the cause, no file in the output directory and inputs
unchanged (the ``refused`` fixture of tests/conftest.py); a good chunk still corrects.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import InputError
from brdfcorr.tasks.request import Engine
from brdfcorr.testing import write_scene_chain

CHUNK_MESSAGE = r"Invalid value for '--chunk': {} must be a multiple of 16 from 16 to 8192"


def _assess_args(scene, chunk: str) -> list:
    return ["assess", scene["image"], scene["image"], "--classes", scene["classes"], "--angles", scene["angles"],
            "-o", scene["out"] / "report.json", "--chunk", chunk]


def _assess_lines_args(scene, chunk: str) -> list:
    return ["assess-lines", scene["image"], scene["image"], "--classes", scene["classes"], "--classes",
            scene["classes"], "--angles", scene["angles"], "--angles", scene["angles"],
            "-o", scene["out"] / "lines.json", "--chunk", chunk]


@pytest.mark.parametrize("command, chunk", [
    ("correct", "0"), ("correct", "-16"), ("correct", "17"), ("correct", "8208"),
    ("assess", "0"), ("assess-lines", "-16"),
])
def test_chunk_sizes_are_refused_while_parsing(scene, command, chunk, refused, correct_args):
    args = {"correct": lambda: correct_args(scene, "--chunk", chunk),
            "assess": lambda: _assess_args(scene, chunk),
            "assess-lines": lambda: _assess_lines_args(scene, chunk)}[command]()
    line = refused(scene, args, CHUNK_MESSAGE.format(re.escape(chunk)))
    assert f"(see --help of {command})" in line


def test_chunk_that_is_no_integer_is_refused(scene, refused, correct_args):
    refused(scene, correct_args(scene, "--chunk", "1e3"), r"Invalid value for '--chunk': '1e3' is not an integer")


@pytest.mark.parametrize("command, chunk, override", [
    ("run", 0, None), ("run", -16, None), ("validate", 0, None), ("run", 16, "engine.chunk=0"),
])
def test_chain_engine_chunk_is_refused(scene, monkeypatch, command, chunk, override, refused):
    monkeypatch.chdir(scene["dir"].parent)
    chain = write_scene_chain(scene["dir"], engine={"scheduler": "synchronous", "workers": 1, "chunk": chunk})
    value = "0" if override else str(chunk)
    refused(scene, [command, chain, *(["--set", override] if override else [])],
            rf"chain\.yaml: engine\.chunk: chunk {value} must be a multiple of 16 from 16 to 8192")


@pytest.mark.parametrize("chunks", [0, -16, 24])
def test_library_engine_refuses_the_same_chunks(chunks):
    with pytest.raises(InputError, match=f"chunk size {chunks} must be a multiple of 16"):
        Engine(chunks=chunks)
    assert Engine(chunks=np.int64(32)).chunks == 32 and Engine().chunks is None


def test_a_good_chunk_still_corrects(scene, correct_args):
    result = CliRunner().invoke(main, [str(a) for a in correct_args(scene, "--chunk", "32")])
    assert result.exit_code == 0, result.output
    assert scene["output"].is_file()
