"""The class-fit figure of ``fit-classes --plot-dir`` (brdfcorr.plot.materials.plot_class_fit): lines
flown under different suns are told apart, each line's model values labelled with its sun zenith."""

from types import SimpleNamespace

import numpy as np

from brdfcorr.fit.sampling import ClassSamples
from brdfcorr.models import get_model
from brdfcorr.plot.materials import plot_class_fit, sun_zenith_groups

PARAMS = {"f_iso": np.array([0.03, 0.3]), "f_vol": np.array([0.02, 0.1]), "f_geo": np.array([0.004, 0.02])}


def _samples(suns) -> ClassSamples:
    rng = np.random.default_rng(2)
    theta_i = np.concatenate([sun + rng.uniform(-0.2, 0.2, 50) for sun in suns])
    theta_r = rng.uniform(0, 18, theta_i.size)
    phi = rng.choice([30.0, 150.0], theta_i.size)
    model = get_model("ross_thick_li_sparse")
    brdf = np.stack([model(theta_i, theta_r, phi, **{k: v[b] for k, v in PARAMS.items()}) for b in range(2)], axis=1)
    return ClassSamples(theta_i, theta_r, phi, brdf)


def _fit():
    return SimpleNamespace(model="ross_thick_li_sparse", params=PARAMS, r2=np.array([0.9, 0.8]), class_id=5,
                           name="grass", status="ok", n_samples=100, vza_spread=36.0)


def test_two_lines_under_two_suns_are_two_labelled_model_curves():
    samples = _samples((30.0, 45.0))
    figure = plot_class_fit(_fit(), samples, wavelengths=[650.0, 860.0])
    axis = figure.axes[0]
    fits = [line for line in axis.get_lines() if "fit" in line.get_label()]
    assert [line.get_label() for line in fits] == ["ross_thick_li_sparse fit, sun zenith 30°",
                                                   "ross_thick_li_sparse fit, sun zenith 45°"]
    assert fits[0].get_color() != fits[1].get_color()
    # Each curve is its line's model values: the samples of that sun only.
    assert all(len(line.get_xdata()) == 50 for line in fits)
    observed = [line for line in axis.get_lines() if line.get_label().startswith("observed")]
    assert [line.get_color() for line in observed] == [line.get_color() for line in fits]
    labels = [text.get_text() for text in figure.legends[0].get_texts()]
    assert "observed, sun zenith 45°" in labels


def test_one_sun_is_one_curve_without_a_sun_label():
    figure = plot_class_fit(_fit(), _samples((30.0,)), wavelengths=[650.0, 860.0])
    assert [line.get_label() for line in figure.axes[0].get_lines()] == ["observed", "ross_thick_li_sparse fit"]


def test_sun_zenith_groups_split_at_gaps_and_give_up_on_many_orbits():
    groups = sun_zenith_groups([30.1, 44.8, 29.9, 45.3, 30.4])
    assert [members.tolist() for members, _ in groups] == [[0, 2, 4], [1, 3]]
    assert [label for _, label in groups] == [", sun zenith 30°", ", sun zenith 45°"]
    assert len(sun_zenith_groups(np.arange(20.0, 60.0, 2.5))) == 1  # a composite: no per-line colours
