"""Two-lobe models: a diffuse/backscatter part plus a specular lobe, fitted jointly.

Real building materials do both: rough ones (concrete, shingle, plaster, rough brick) scatter
mostly back towards the sun (shadow hiding, the hot spot), glossy ones (tiles, slate, painted metal)
into a broadened specular peak, and many show the two at once. A single-lobe model misses one half:
the Torrance-Sparrow default of paper 003 predicts nothing in the backscatter half, the kernel-driven
models nothing in the forward peak. A two-lobe model is the sum of the two::

    ross_li_ts:    f = f_iso + f_vol K_vol + f_geo K_geo + t1 S(w, n, k)
    ross_li_peak:  f = f_iso + f_vol K_vol + f_geo K_geo + a E(b, c)
    rpv_peak:      f = rho0 R(k, theta, rho_c)            + a E(b, c)

with K_vol, K_geo the Ross-Thick and Li-Sparse-Reciprocal kernels (:mod:`brdfcorr.models.kernels`),
S the specular term of Torrance-Sparrow with its Fresnel and V-cavity factors
(:mod:`brdfcorr.models.torrance_sparrow`, paper 003 eq. 1, without its Lambertian t0: f_iso takes
that role), E the empirical peak of paper 000 (eq. 5) and R the RPV shape (:mod:`brdfcorr.models.rpv`).
Each part keeps its parameters' names, units and bounds, so a table entry of a two-lobe class reads
like the entries of its two parts. Every part is linear in its intensity (f_iso, f_vol, f_geo, t1,
a, rho0), so the fits solve those by linear least squares for a trial lobe shape (variable
projection, :mod:`brdfcorr.fit.solver`).

Each part is reciprocal and non-negative for non-negative intensities, so their sum is too.

References
----------
.. [1] M. Stavridi, B. van Ginneken, J. J. Koenderink (1997): Surface bidirectional reflection
   distribution function and the texture of bricks and tiles. Appl. Opt. 36(16), 3717-3725 (a
   diffuse rough-surface model plus a specular lobe fitted to bricks and tiles).
.. [2] W. Lucht, C. B. Schaaf, A. H. Strahler (2000): An algorithm for the retrieval of albedo from
   space using semiempirical BRDF models. IEEE TGRS 38(2), 977-998.
.. [3] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII, eq. 1.
"""

from __future__ import annotations

from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models._base import Model
from brdfcorr.models.empirical import EMPIRICAL
from brdfcorr.models.kernels import ROSS_THICK_LI_SPARSE
from brdfcorr.models.rpv import RPV
from brdfcorr.models.torrance_sparrow import TORRANCE_SPARROW

__all__ = ["two_lobe", "ROSS_LI_TS", "ROSS_LI_PEAK", "RPV_PEAK", "TWO_LOBE_MODELS"]


def two_lobe(name: str, description: str, diffuse: Model, lobe: Model, lobe_terms: tuple[str, ...]) -> Model:
    """The model ``diffuse + lobe``: every parameter of ``diffuse`` plus the lobe's intensity
    terms ``lobe_terms`` and its shape parameters (the lobe's other intensity terms, such as the
    Lambertian t0 of Torrance-Sparrow, are left out: the diffuse part has its own).

    Parameters
    ----------
    name, description : str
        Registry name and one line for tables and docs.
    diffuse : Model
        The diffuse/backscatter part (a kernel-driven model, RPV), with intensity terms.
    lobe : Model
        The specular part (Torrance-Sparrow, the empirical peak).
    lobe_terms : tuple of str
        The lobe's intensity terms kept (``("t1",)`` of Torrance-Sparrow, ``("a",)`` of the peak).

    Raises
    ------
    ValueError
        When the parts share a parameter name or ``lobe_terms`` are not intensity terms of the lobe.
    """
    if not set(lobe_terms) <= set(lobe.linear):
        raise ValueError(f"{name}: {lobe_terms} are not intensity terms of {lobe.name}")
    lobe_parameters = tuple(p for p in lobe.parameters if p.name in lobe_terms or p.name in lobe.shape_names)
    shared = set(diffuse.parameter_names) & {p.name for p in lobe_parameters}
    if shared:
        raise ValueError(f"{name}: {diffuse.name} and {lobe.name} share the parameter(s) {sorted(shared)}")
    kept = [index for index, term in enumerate(lobe.linear) if term in lobe_terms]
    linear = diffuse.linear + tuple(lobe.linear[index] for index in kept)

    def basis(geometry: ScatteringGeometry, **shape):
        lobe_basis = lobe.terms(geometry, shape)
        return diffuse.terms(geometry, shape) + tuple(lobe_basis[index] for index in kept)

    def kernel(geometry: ScatteringGeometry, **params):
        terms = basis(geometry, **{key: params[key] for key in params if key not in linear})
        total = 0.0
        for term_name, term in zip(linear, terms):
            total = total + params[term_name] * term
        return total

    return Model(
        name=name,
        description=description,
        reference=f"{diffuse.reference} + {lobe.reference}; two lobes as in Stavridi et al. (1997)",
        parameters=diffuse.parameters + lobe_parameters,
        kernel=kernel,
        linear=linear,
        basis=basis,
    )


ROSS_LI_TS = two_lobe(
    "ross_li_ts",
    "Ross-Thick/Li-Sparse-Reciprocal kernels (backscatter, hot spot) plus a Torrance-Sparrow specular "
    "lobe with Fresnel and masking/shadowing",
    ROSS_THICK_LI_SPARSE, TORRANCE_SPARROW, ("t1",),
)
ROSS_LI_PEAK = two_lobe(
    "ross_li_peak",
    "Ross-Thick/Li-Sparse-Reciprocal kernels plus the empirical specular peak of paper 000",
    ROSS_THICK_LI_SPARSE, EMPIRICAL, ("a",),
)
RPV_PEAK = two_lobe(
    "rpv_peak",
    "Rahman-Pinty-Verstraete (backscatter, hot spot) plus the empirical specular peak of paper 000",
    RPV, EMPIRICAL, ("a",),
)

#: The registered two-lobe models.
TWO_LOBE_MODELS: tuple[Model, ...] = (ROSS_LI_TS, ROSS_LI_PEAK, RPV_PEAK)
