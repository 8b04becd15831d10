"""The choice of a surface model by held-out error (--model auto)."""

import json
import math

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import FitError, ParameterError
from brdfcorr.fit.classes import ClassFitWarning, ClassModels, _models_in_play, fit_classes, fit_one_class
from brdfcorr.fit.measurements import Measurements
from brdfcorr.fit.sampling import ClassSamples
from brdfcorr.fit.selection import (
    CandidateScore,
    _folds,
    _one_se_choice,
    check_fixed,
    choose_class_model,
    choose_model,
)
from brdfcorr.models import get_model
from brdfcorr.testing import synthetic_scene

TWO_LOBE = {"f_iso": 0.03, "f_vol": 0.02, "f_geo": 0.004, "t1": 0.2, "w": 0.0362, "n": 1.77, "k": 0.25}
KERNELS = {"f_iso": 0.05, "f_vol": 0.03, "f_geo": 0.01}


def _geometries():
    """Both halves of the azimuth circle, zeniths <= 60 deg (75 geometries)."""
    grid = np.meshgrid([10, 25, 40, 55], [0, 15, 30, 45, 60], [0, 45, 90, 135, 180], indexing="ij")
    return tuple(np.asarray(a, dtype=float).ravel() for a in grid)


def test_the_one_standard_error_rule_keeps_the_simpler_model_unless_the_complex_one_wins_clearly():
    simple = CandidateScore("simple", 3, (1.00, 1.10, 0.90, 1.05, 0.95), 0.9)
    # Fold by fold the complex model is better by 0.05, -0.04, 0.03, -0.02, 0.01: mean 0.006, paired
    # standard error 0.036 / sqrt(5) = 0.016: it does not win by more than the folds' spread.
    close = CandidateScore("complex", 6, (0.95, 1.14, 0.87, 1.07, 0.94), 0.91)
    assert _one_se_choice([simple, close]) == ("simple", "complex")
    clear = CandidateScore("complex", 6, (0.50, 0.60, 0.45, 0.55, 0.50), 0.95)  # wins in every fold
    assert _one_se_choice([simple, clear]) == ("complex", "complex")
    broken = CandidateScore("broken", 2, (), float("nan"), "did not converge")
    assert _one_se_choice([broken, simple]) == ("simple", "simple")
    with pytest.raises(FitError, match="broken: did not converge"):
        _one_se_choice([broken])


def test_folds_keep_each_group_whole_and_are_balanced():
    groups = np.repeat(np.arange(23), 7)
    fold = _folds(groups, 5, seed=0)
    for group in np.unique(groups):
        assert np.unique(fold[groups == group]).size == 1
    counts = np.bincount(fold)
    assert counts.size == 5 and counts.max() - counts.min() <= 7


def test_a_two_lobe_surface_chooses_the_two_lobe_model_and_a_kernel_surface_the_kernels():
    ti, tr, phi = _geometries()
    noise = 1 + 0.02 * np.random.default_rng(5).standard_normal(ti.size)
    candidates = ("torrance_sparrow", "ross_thick_li_sparse", "ross_li_ts")
    two_lobe = choose_model(Measurements(ti, tr, phi, get_model("ross_li_ts")(ti, tr, phi, **TWO_LOBE) * noise),
                            candidates=candidates)
    assert two_lobe.chosen == "ross_li_ts" and two_lobe.score_of("ross_li_ts").heldout_r2 > 0.95
    assert max(two_lobe.score_of(name).heldout_r2 for name in candidates[:2]) < 0.9
    kernels = choose_model(Measurements(ti, tr, phi, get_model("ross_thick_li_sparse")(ti, tr, phi, **KERNELS) * noise),
                           candidates=candidates)
    # The two-lobe model nests the kernels: it cannot win by more than the folds' spread.
    assert kernels.chosen == "ross_thick_li_sparse"
    assert [row["chosen"] for row in kernels.rows()] == [False, True, False]


def test_the_fold_fits_in_a_process_pool_give_the_same_choice():
    # `fit --model auto --workers N` hands the candidates' fold fits to processes: each fit is the
    # same computation, so every fold's held-out error is the same to the last bit.
    from brdfcorr.tasks.pool import process_pool

    ti, tr, phi = _geometries()
    brdf = get_model("ross_thick_li_sparse")(ti, tr, phi, **KERNELS) * (1 + 0.02 * np.random.default_rng(3).standard_normal(ti.size))
    candidates = ("ross_thick_li_sparse", "torrance_sparrow")
    alone = choose_model(Measurements(ti, tr, phi, brdf), candidates=candidates)
    with process_pool(2, ("brdfcorr.fit.selection",)) as pool:
        pooled = choose_model(Measurements(ti, tr, phi, brdf), candidates=candidates, executor=pool, progress=(done := []).append)
    assert pooled == alone and alone.chosen == "ross_thick_li_sparse"
    assert done == list(candidates)


def test_leaving_the_fold_pool_early_cancels_the_fits_not_started():
    # Ctrl-C during `fit --model auto`: the pool waits for the fits running, not for all thirty.
    import time

    from brdfcorr.tasks.pool import process_pool

    futures = []
    with pytest.raises(KeyboardInterrupt), process_pool(2, ()) as pool:
        futures = [pool.submit(time.sleep, 0.5) for _ in range(20)]
        raise KeyboardInterrupt
    assert sum(future.cancelled() for future in futures) >= 15


def test_where_no_process_pool_can_be_made_the_fits_run_here_and_say_so(monkeypatch):
    # A system without POSIX semaphores (no /dev/shm: AWS Lambda, some containers) refuses a
    # process pool; `fit --model auto` then fits in its own process instead of failing.
    import concurrent.futures

    from brdfcorr.errors import BrdfcorrWarning
    from brdfcorr.tasks.pool import process_pool

    def refused(*args, **kwargs):
        raise OSError(38, "Function not implemented")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", refused)
    with pytest.warns(BrdfcorrWarning, match="no worker processes can be started here"), process_pool(4, ()) as pool:
        assert pool is None


def test_bounds_and_starting_values_apply_in_the_choice_to_the_candidates_that_have_them():
    # Each candidate is scored as it would be fitted: a bound on w (the Torrance-Sparrow lobe's
    # width) holds in every fold fit of torrance_sparrow and leaves ross_thick_li_sparse (no w) as
    # it was. Independent computation: the same folds (_folds, seed SEED) fitted with fit_from from
    # the bounded fit to all the measurements (fit_brdf).
    from brdfcorr.fit.goniometer import fit_brdf, fit_from
    from brdfcorr.fit.selection import SEED
    from brdfcorr.models.materials import load_material

    ti, tr, phi = _geometries()
    truth = load_material("roof_tile").params  # w = 0.037 deg^-1
    brdf = get_model("torrance_sparrow")(ti, tr, phi, **truth) * (1 + 0.02 * np.random.default_rng(7).standard_normal(ti.size))
    candidates = ("torrance_sparrow", "ross_thick_li_sparse")
    free = choose_model(Measurements(ti, tr, phi, brdf), candidates=candidates, folds=3)
    bounds, initial = {"w": (0.15, 0.5)}, {"w": 0.2, "f_iso": 0.02}
    bounded = choose_model(Measurements(ti, tr, phi, brdf), candidates=candidates, bounds=bounds, initial=initial, folds=3)
    # (ross_thick_li_sparse is linear: a start more, f_iso = 0.02, reaches the same least squares)
    np.testing.assert_allclose(bounded.score_of("ross_thick_li_sparse").fold_errors,
                               free.score_of("ross_thick_li_sparse").fold_errors, rtol=1e-6)
    fold = _folds(np.arange(ti.size), 3, SEED)
    expected = []
    with pytest.warns(Warning):  # (w ends on its bound)
        whole = fit_brdf("torrance_sparrow", ti, tr, phi, brdf, fixed={"k": 0.25}, bounds=bounds, initial={"w": 0.2})
        start = {name: whole.params[name] for name in whole.free}
        for number in range(3):
            train, test = fold != number, fold == number
            fit = fit_from("torrance_sparrow", ti[train], tr[train], phi[train], brdf[train], start=start,
                           fixed={"k": 0.25}, bounds=bounds)
            expected.append(np.mean((fit.predict(ti[test], tr[test], phi[test]) - brdf[test]) ** 2))
    np.testing.assert_allclose(bounded.score_of("torrance_sparrow").fold_errors, expected, rtol=1e-9)
    assert bounded.score_of("torrance_sparrow").mean_error > 10 * free.score_of("torrance_sparrow").mean_error
    assert (free.chosen, bounded.chosen) == ("torrance_sparrow", "ross_thick_li_sparse")


def test_too_few_measurements_for_the_folds_are_refused():
    with pytest.raises(FitError, match="too few"):
        choose_model(Measurements([10, 20], [10, 20], [0, 180], [0.1, 0.2]))


def _class_samples(params, model="ross_li_ts", n=6000, seed=1):
    rng = np.random.default_rng(seed)
    ti, tr = rng.uniform(25, 45, n), rng.uniform(0, 40, n)
    phi = np.where(rng.random(n) < 0.5, rng.uniform(0, 20, n), rng.uniform(160, 180, n))
    brdf = np.column_stack([get_model(model)(ti, tr, phi, **{**params, "f_iso": params["f_iso"] * scale})
                            for scale in (1.0, 2.0)])
    brdf = brdf * (1 + 0.01 * rng.standard_normal(brdf.shape))
    return ClassSamples(ti, tr, phi, brdf, block=rng.integers(0, 40, n))


def test_a_torrance_sparrow_class_gets_its_own_model_and_the_folds_reach_the_fit_to_all_the_pixels():
    # Red concrete (paper 003's Torrance-Sparrow fit) in two bands, 3 % noise, from every azimuth.
    # Each fold's own coarse-grid search stopped short of the minimum (held-out R^2 0.990 where
    # the fit reaches 0.995), and ross_li_ts, which nests the lobe, won the choice by that margin.
    # The folds now start from the shape fitted to all the pixels: the simplest model that
    # predicts the held-out blocks as well as any is chosen.
    from brdfcorr.models.materials import load_material

    truth = dict(load_material("red_concrete").params)
    rng = np.random.default_rng(1)
    n = 6000
    ti, tr, phi = rng.uniform(20, 50, n), rng.uniform(0, 40, n), rng.uniform(0, 180, n)
    model = get_model("torrance_sparrow")
    brdf = np.column_stack([model(ti, tr, phi, **truth), model(ti, tr, phi, **{**truth, "t1": 0.8 * truth["t1"]})])
    brdf = brdf * (1 + 0.03 * rng.standard_normal(brdf.shape))
    choice = choose_class_model(ClassSamples(ti, tr, phi, brdf, block=np.arange(n) // 60))
    assert choice.chosen == "torrance_sparrow"
    own, nesting = choice.score_of("torrance_sparrow").heldout_r2, choice.score_of("ross_li_ts").heldout_r2
    assert own > 0.993 and abs(own - nesting) < 1e-3


def test_a_class_fitted_with_auto_gets_the_held_out_choice_and_reports_it():
    samples = _class_samples(TWO_LOBE)
    choice = choose_class_model(samples)
    assert choice.grouping == "spatial blocks" and choice.chosen == "ross_li_ts"
    fit = fit_one_class(3, "glazed_tile", "auto", samples)
    assert fit.model == "ross_li_ts" and fit.status == "fitted"
    assert fit.params["w"][0] == pytest.approx(0.0362, rel=0.05)
    summary = json.loads(json.dumps(fit.summary()))
    assert summary["model_choice"]["chosen"] == "ross_li_ts"
    assert {row["model"] for row in summary["model_choice"]["candidates"]} >= {"torrance_sparrow", "ross_li_ts"}


def test_a_class_in_one_block_cannot_be_chosen_for_and_says_so():
    samples = _class_samples(TWO_LOBE, n=2000)
    samples.block[:] = 7
    with pytest.warns(ClassFitWarning):  # the kernels fitted instead explain none of this tile's peak
        fit = fit_one_class(3, "tile", "auto", samples)
    assert fit.model_choice is None and any("no held-out choice" in note for note in fit.notes)


def test_cli_fit_auto_prints_the_candidates_and_writes_the_chosen_model(tmp_path):
    ti, tr, phi = _geometries()
    brdf = get_model("ross_li_ts")(ti, tr, phi, **TWO_LOBE) * (1 + 0.02 * np.random.default_rng(2).standard_normal(ti.size))
    csv = tmp_path / "tile.csv"
    csv.write_text("theta_i,theta_r,phi,brdf\n" + "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in zip(ti, tr, phi, brdf)))
    result = CliRunner().invoke(main, ["fit", str(csv), "--model", "auto", "-o", str(tmp_path / "t.yaml"),
                                       "--plot-dir", str(tmp_path / "plots")])
    assert result.exit_code == 0, result.output
    figure = tmp_path / "plots" / "tile_model_choice.png"  # every candidate's held-out error, a figure
    assert figure.read_bytes().startswith(b"\x89PNG")
    assert "model choice by 5-fold cross-validation over geometries" in result.output
    assert "ross_li_ts" in result.output and "<- chosen" in result.output
    table = (tmp_path / "t.yaml").read_text()
    assert "model: ross_li_ts" in table and "chosen by 5-fold cross-validation" in table
    refused = CliRunner().invoke(main, ["fit", str(csv), "--model", "best"])
    assert refused.exit_code == 2 and "unknown BRDF model 'best'" in refused.output
    # Starting values and bounds are checked against the candidates before the choice's fits: a
    # name none has, or one that is another parameter in two of them (k: Torrance-Sparrow's
    # absorption index, RPV's exponent), is one line, not an error after every fold's fit.
    for option, value, message in (("--init", "f_vol2=0.1", "starting value of f_vol2 is a parameter of none"),
                                   ("--bound", "k=0.1:0.5", "bound of parameter k is not the same parameter")):
        refused = CliRunner().invoke(main, ["fit", str(csv), "--model", "auto", option, value])
        assert refused.exit_code == 2 and message in refused.output, refused.output


def test_the_model_choice_figure_has_one_bar_per_candidate_and_names_the_chosen():
    from brdfcorr.fit.selection import CandidateScore, ModelChoice
    from brdfcorr.plot.model_choice import plot_model_choice

    choice = ModelChoice("ross_li_ts", "ross_li_ts", (
        CandidateScore("torrance_sparrow", 4, (2.0, 3.0), 0.3),
        CandidateScore("ross_li_ts", 7, (0.1, 0.2), 0.97),
        CandidateScore("rpv", 4, (), math.nan, "did not converge"),
    ), 2, "geometries")
    figure = plot_model_choice(choice, "tile")
    left, right = figure.axes
    assert [label.get_text() for label in left.get_yticklabels()] == [
        "torrance_sparrow (4)", "ross_li_ts (7)", "rpv (4)"]
    widths = [patch.get_width() for patch in left.patches]
    assert widths == pytest.approx([2.5, 0.15, 0.0])  # mean fold errors; none for the unfitted
    assert "ross_li_ts chosen" in figure.texts[0].get_text()


def test_a_fixed_name_that_is_a_different_parameter_in_two_candidates_is_refused(tmp_path):
    # k is RPV's Minnaert-like exponent and the Torrance-Sparrow models' absorption index (the
    # registry's parameters): --fix k=0.25 with --model auto held RPV's exponent at 0.25 silently.
    ti, tr, phi = _geometries()
    brdf = get_model("ross_li_ts")(ti, tr, phi, **TWO_LOBE)
    with pytest.raises(ParameterError, match=r"fixed parameter k .*Minnaert-like exponent.* in rpv, rpv_peak"):
        choose_model(Measurements(ti, tr, phi, brdf), fixed={"k": 0.25})
    check_fixed({"k": 0.25}, ("torrance_sparrow", "ross_li_ts", "ross_thick_li_sparse"))  # one meaning: kept
    csv = tmp_path / "tile.csv"
    csv.write_text("theta_i,theta_r,phi,brdf\n" + "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in zip(ti, tr, phi, brdf)))
    refused = CliRunner().invoke(main, ["fit", str(csv), "--model", "auto", "--fix", "k=0.25"])
    assert refused.exit_code == 2 and "fixed parameter k is not the same parameter" in refused.output
    models = ClassModels("torrance_sparrow", class_models={2: "rpv"}, fixed={"k": 0.3})
    assert _models_in_play(models) == ["torrance_sparrow", "rpv"]
    with pytest.raises(ParameterError, match="fixed parameter k"):
        scene = synthetic_scene(ny=8, nx=8)
        fit_classes(scene["reflectance"], scene["classes"], xr.Dataset({a: scene[a] for a in ("sza", "saa", "vza", "vaa")}), models)


def test_candidates_that_all_predict_to_round_off_tie_and_the_simplest_is_chosen():
    # A perfectly flat BRDF (a Lambertian panel, noise-free): every candidate predicts it to the
    # optimizer's round-off (held-out errors 1e-14 to 1e-22), and the one-SE rule ranked that
    # round-off: rpv_peak (7 free parameters) was chosen. Ross-Thick-Li-Sparse (3) fits it exactly.
    ti, tr, phi = _geometries()
    flat = np.full(ti.size, 0.05)
    choice = choose_model(Measurements(ti, tr, phi, flat, np.full(ti.size, 0.001)))
    assert choice.chosen == "ross_thick_li_sparse"
