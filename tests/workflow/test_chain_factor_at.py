"""The chain's correct step takes ``factor_at`` as ``brdfcorr correct --factor-at`` does; its
default is not recorded in the outputs' fingerprint, so outputs made before the key existed stay
current on a resumed run."""

from __future__ import annotations

import json

import pytest

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import plan_run, run_chain
from brdfcorr.errors import ConfigError


def test_the_default_is_not_in_the_fingerprint_and_nodes_is(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    default = json.loads(plan_run(load_config(chain)).scenes[0].fingerprint)
    assert "factor_at" not in default["correct"]
    nodes = json.loads(plan_run(load_config(chain, {"steps.correct.factor_at": "nodes"})).scenes[0].fingerprint)
    assert nodes["correct"]["factor_at"] == "nodes"
    assert {key: value for key, value in nodes["correct"].items() if key != "factor_at"} == default["correct"]


def test_an_unknown_value_names_the_key_and_the_allowed_ones(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    with pytest.raises(ConfigError, match=r"steps\.correct\.factor_at.*'pixels'.*'nodes'"):
        load_config(write_chain(tmp_path, steps={"correct": {"factor_at": "corners"}}))


def test_nodes_on_per_pixel_angles_and_a_class_map_fails_the_scene_in_one_line(tmp_path, make_scenes, write_chain):
    # write_chain's scenes have a class map and per-pixel angle rasters: the nodes do not apply.
    make_scenes(tmp_path, count=1)
    report = run_chain(load_config(write_chain(tmp_path, steps={"correct": {"factor_at": "nodes"}})))
    assert not report.ok
    [scene] = report.scenes
    assert scene["status"] == "failed" and "nodes with a class map" in scene["error"]
    assert not (tmp_path / "out" / "line0_brdf.tif").exists()
