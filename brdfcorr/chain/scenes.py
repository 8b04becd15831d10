"""The scenes of a chain run: one per input image (or product), with its files and what happens to it.

:func:`input_images` expands the config's image patterns, :func:`plan_scenes` makes a
:class:`Scene` of each (its name, class map, angle source, terrain source and output names, from
the config's patterns: :mod:`brdfcorr.chain.patterns`) and decides its action from the files alone
(``run``, ``skip``, ``fail``); :mod:`brdfcorr.chain.resume` then checks the skipped ones, and
:func:`brdfcorr.chain.plan.plan_run` puts it together.
"""

from __future__ import annotations

import dataclasses
import glob
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import rasterio
import rasterio.errors

from brdfcorr.chain.config import ChainConfig, format_pattern
from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.io.sensors.inputs import products_among
from brdfcorr.plot.assess import figure_paths

if TYPE_CHECKING:
    from brdfcorr.io.sensors.folders import ProductFolder

__all__ = ["Scene", "input_images", "plan_scenes", "check_quicklook_bands"]


@dataclass(frozen=True)
class Scene:
    """One input image and everything the chain reads and writes for it.

    Attributes
    ----------
    name : str
        Scene name (``{scene}`` in patterns).
    image : Path
        Reflectance image (or product folder).
    classes : Path or None
        Class map; None: one class over the whole image (a coefficient set as ``parameters.table``
        without ``inputs.classes``), or a scene that failed before its files were named.
    angles_kind : str
        Angle source kind (``geotiff``, ``envi_obs``, ...).
    angles : str
        The angle source: a path, or for ``solar`` the acquisition time.
    angle_options : dict
        Options of the angle reader.
    outputs : dict of str to Path
        ``corrected`` and, when enabled, ``strata`` (the class map ``steps.strata`` derives, then
        also ``classes``), ``qa``, ``uncertainty``, ``assess`` (JSON report), ``assess_profiles``
        (its figure) and ``quicklook``.
    action : {"run", "skip", "fail"}
        What the run will do; ``reason`` says why for ``skip`` and ``fail`` (and for ``run`` when
        existing outputs are redone).
    fingerprint : str
        What the corrected output will record of its inputs and settings
        (:func:`brdfcorr.chain.resume.scene_fingerprint`).
    slope_aspect, dem : Path, optional
        The terrain source of ``steps.correct.terrain`` (one of them, or neither).
    clusters : Path, optional
        The cluster layer the assess step reads (``steps.assess.clusters``).
    product : ProductFolder, optional
        For a product (``image`` a product folder or STAC item, :mod:`brdfcorr.chain.products`):
        the product as the plan found it (its metadata read once per run; the run stacks its bands
        from it, :func:`brdfcorr.chain.products.stacked_scenes`); None for an image file.
    product_files : tuple of (str, Path)
        For a product, every file it reads, by role (bands, quality mask, angle metadata: its
        :attr:`~brdfcorr.io.sensors.folders.ProductFolder.files` when planned); empty for an image file.
    stack, scale, offset : optional
        For a product, during a run only (:func:`brdfcorr.chain.products.stacked_scenes`): the
        stacked bands read as the scene's image (a VRT in the run's scratch folder) and the
        product's reflectance scaling (reflectance = DN x scale + offset) where every band has
        the same.
    """

    name: str
    image: Path
    classes: Path | None
    angles_kind: str
    angles: str
    angle_options: dict
    outputs: dict
    action: str = "run"
    reason: str = ""
    fingerprint: str = ""
    slope_aspect: Path | None = None
    dem: Path | None = None
    clusters: Path | None = None
    product: ProductFolder | None = None
    product_files: tuple[tuple[str, Path], ...] = ()
    stack: Path | None = None
    scale: float | None = None
    offset: float | None = None

    @property
    def raster(self) -> Path:
        """The raster the steps read: the image, or a product's stack."""
        return self.image if self.stack is None else self.stack

    def scaling(self, scale: float | None, offset: float | None) -> dict:
        """``scale`` and ``offset`` of :class:`~brdfcorr.io.scene.SceneSources`: a product's own
        (None where its bands differ: each band's GDAL scale), else the given ones (``inputs``)."""
        if self.product is not None:
            return {"scale": self.scale, "offset": self.offset}
        return {"scale": scale, "offset": offset}

    def inputs(self) -> list[tuple[str, Path]]:
        """(role, path) of the files the scene reads: image (or product and its files), class map
        (unless the chain derives it, ``outputs["strata"]``), angle file, the terrain source and
        the assess step's cluster layer."""
        files = [("product", self.image), *self.product_files] if self.product is not None else [("image", self.image)]
        # None: one class over the whole image, or a scene failed before its files were named
        if self.classes is not None and self.outputs.get("strata") != self.classes:
            files.append(("class map", self.classes))
        # the solar source is a time, not a file; a product's angle files are among its files
        if self.angles_kind != "solar" and self.angles and self.product is None:
            files.append(("angles", Path(self.angles)))
        files += [(role, path) for role, path in (("slope/aspect", self.slope_aspect), ("DEM", self.dem),
                                                  ("cluster layer", self.clusters)) if path is not None]
        return files

    def describe(self) -> dict:
        """JSON-friendly description (for the report and ``--dry-run``)."""
        return {
            "scene": self.name,
            "image": str(self.image),
            **({"product": True} if self.product is not None else {}),
            "angles": {"kind": self.angles_kind, "source": self.angles, **(
                {"options": {key: value if isinstance(value, (str, int, float, bool)) else str(value)
                             for key, value in self.angle_options.items()}} if self.angle_options else {})},
            "classes": None if self.classes is None else str(self.classes),
            **{role: str(path) for role, path in (("slope_aspect", self.slope_aspect), ("dem", self.dem),
                                                  ("clusters", self.clusters)) if path is not None},
            "outputs": {key: str(value) for key, value in self.outputs.items()},
            "action": self.action,
            **({"reason": self.reason} if self.reason else {}),
        }


def input_images(config: ChainConfig, require_inputs: bool) -> tuple[list[Path], list[str]]:
    """The input images (globs expanded, duplicates dropped) and notes on patterns matching nothing."""
    images, notes, typo = [], [], False
    for item in config.inputs.images:
        pattern = str(config.resolve(item))
        if glob.has_magic(pattern):
            # files, and folders: product folders (a mix with files is refused by plan_scenes)
            matches = sorted(Path(p) for p in glob.glob(pattern) if Path(p).is_file() or Path(p).is_dir())
            if not matches:
                notes.append(f"inputs.images: {item!r} matches no file")
                typo = typo or _glob_root(pattern).is_dir()
            images += matches
        else:
            images.append(Path(pattern))
    images = list(dict.fromkeys(images))  # as given: a link stays a link ({dir} is its directory)
    # A pattern matching nothing is a typo, not an empty batch: an error, also without
    # require_inputs (validate, --dry-run) where its folder exists; only the data of a folder
    # that does not exist yet may be missing there (a warning).
    if not images:
        message = f"inputs.images matches no file ({', '.join(config.inputs.images)})"
        if require_inputs or typo:
            raise InputError(f"{config.source}: {message}")
        notes = [message]
    elif notes and (require_inputs or typo):
        raise InputError(f"{config.source}: {'; '.join(notes)} (fix or remove the pattern)")
    return images, notes


def _glob_root(pattern: str) -> Path:
    """The folder of a glob pattern up to its first wildcard (``data/*/x.tif`` -> ``data``)."""
    parts = Path(pattern).parts
    fixed = next(index for index, part in enumerate(parts) if glob.has_magic(part))
    return Path(*parts[:fixed]) if fixed else Path()


def check_quicklook_bands(config: ChainConfig, scenes: list[Scene]) -> None:
    """Refuse quicklook bands beyond the band count of an input image (read from the file's header),
    before anything is corrected: one band list serves the whole batch, so an image with fewer
    bands means the setting is wrong, as a glob typo is. Images that are missing or unreadable are
    left to their scene (which fails on them)."""
    step = config.steps.quicklook
    if step is None or step.bands is None:  # chosen by wavelength per image
        return
    needed = max(step.bands)
    short = []
    for scene in scenes:
        if not scene.image.is_file():  # missing (the scene fails) or no regular file: not opened here
            continue
        try:
            with rasterio.open(scene.image) as dataset:
                count = dataset.count
        except (OSError, rasterio.errors.RasterioError):
            continue
        if count < needed:
            short.append(f"{scene.image} has {count}")
    if short:
        more = f" (and {len(short) - 1} more)" if len(short) > 1 else ""
        raise InputError(
            f"{config.source}: steps.quicklook.bands {list(step.bands)} needs {needed} bands, but image "
            f"{short[0]}{more}; choose bands of every image"
        )


def _scene_name(config: ChainConfig, image: Path, shared_stems=frozenset()) -> str:
    regex = config.inputs.scene_regex
    if regex is None:  # the stem, qualified by the directory when several images share it
        return f"{image.parent.name}_{image.stem}" if image.stem in shared_stems else image.stem
    match = re.search(regex, image.name)
    if match is None or not match.group("scene"):
        raise InputError(f"inputs.scene_regex {regex!r} does not match image file name {image.name!r}")
    return match.group("scene")


def plan_scenes(config: ChainConfig, images: list[Path], output_dir: Path,
                fingerprint: Callable[[Scene, ChainConfig], str]) -> list[Scene]:
    """One scene per image, with its action and ``fingerprint(scene, config)``
    (:func:`brdfcorr.chain.resume.scene_fingerprint`); no two scenes may write the same file name
    (:func:`brdfcorr.chain.plan.plan_run` then checks every output against every input and output by
    file identity)."""
    products = _are_products(config, images)
    stems = [image.stem for image in images]
    shared = frozenset(stem for stem in stems if stems.count(stem) > 1)
    scenes, writers = [], {}
    for image in images:
        scene = _plan_scene(config, image, shared, output_dir, fingerprint, products)
        for role, path in scene.outputs.items():
            if path in writers and writers[path] is not scene:  # one scene's own outputs: plan_run
                raise InputError(_collision(config, writers[path], scene, role, path))
            writers[path] = scene
        scenes.append(scene)
    return scenes


#: The naming pattern of each output role (the assessment's files are named by the scene).
_NAMING = {"corrected": "naming", "qa": "qa_naming", "uncertainty": "uncertainty_naming",
           "quicklook": "quicklook_naming", "strata": "strata_naming"}


def _collision(config: ChainConfig, first: Scene, second: Scene, role: str, path: Path) -> str:
    """Why two scenes would write one ``path``, and what tells them apart: one file named twice in
    ``inputs.images``, or the placeholders that ``role``'s naming pattern does not use yet."""
    if first.image.exists() and second.image.exists() and os.path.samefile(first.image, second.image):
        return f"inputs.images names one file twice, as {first.image} and {second.image}: name it once"
    hints, key = ["use a scene_regex giving distinct scene names"], _NAMING.get(role)
    unused = [] if key is None else [field for field in ("{scene}", "{stem}", "{parent}")
                                     if field not in getattr(config.outputs, key)]
    if unused:
        hints.insert(0, f"add {' or '.join(unused)} to outputs.{key} ({getattr(config.outputs, key)!r})")
    return f"outputs: scenes {first.name} ({first.image}) and {second.name} ({second.image}) would both write " \
           f"{path}; {', or '.join(hints)}"


def _are_products(config: ChainConfig, images: list[Path]) -> bool:
    """Whether the run's inputs are products (:func:`brdfcorr.io.sensors.inputs.products_among`: all of
    them, none of the settings that products bring themselves given); images that do not exist
    (their scenes fail) count as neither.

    Raises
    ------
    InputError
        A mix of products and image files; ``inputs.angles``, ``scale``, ``offset`` or
        ``wavelengths`` given with products; image files without ``inputs.angles``.
    """
    inputs = config.inputs
    given = {f"inputs.{key}": getattr(inputs, key) is not None for key in ("angles", "scale", "offset", "wavelengths")}
    try:
        products = products_among([image for image in images if os.path.lexists(image)], given)
    except InputError as error:
        raise InputError(f"{config.source}: {error}") from None
    if not products and inputs.angles is None and any(os.path.lexists(image) for image in images):
        raise InputError(f"{config.source}: inputs.angles is missing: image files need their angle source "
                         "(only product folders bring their own)")
    return products


def _product_fields(image: Path) -> dict:
    """The :class:`Scene` fields that a product brings: the product, found once for the run (from
    its metadata only, :func:`brdfcorr.tasks.series.find_products`; the run stacks its bands from
    it, :mod:`brdfcorr.chain.products`), its angle source and its files.

    Raises
    ------
    BrdfcorrError
        The product is missing, in an archive, or no product (as ``brdfcorr nbar`` says it).
    """
    from brdfcorr.tasks.series import find_products  # the product readers: for product chains only

    if not os.path.lexists(image):
        raise InputError(f"missing input: product {image}")
    [product] = find_products([image])
    return {"angles_kind": product.angles_kind, "angles": str(product.angles),
            "angle_options": dict(product.angle_options), "product": product, "product_files": tuple(product.files)}


def _plan_scene(config: ChainConfig, image: Path, shared_stems: frozenset, output_dir: Path,
                fingerprint: Callable[[Scene, ChainConfig], str], product: bool = False) -> Scene:
    angles = config.inputs.angles
    try:
        name = _scene_name(config, image, shared_stems)
        found = _product_fields(image) if product else {}
    except BrdfcorrError as error:
        return Scene(image.stem, image, None, "" if angles is None else angles.kind, "", {}, {}, "fail", str(error))

    def fill(pattern: str) -> str:
        return format_pattern(pattern, image, name)

    outputs = _output_paths(config, output_dir, fill, name)
    # A derived class map (steps.strata) is an output; a given one is resolved against the config.
    classes = (outputs["strata"] if "strata" in outputs else None if config.inputs.classes is None
               else config.resolve(fill(config.inputs.classes)))
    if angles is None and not product:  # no image exists: its scene fails for that (_action)
        found = {"angles_kind": "", "angles": "", "angle_options": {}}
    elif angles is not None:
        angle_source = fill(angles.path)
        if angles.kind != "solar":  # the solar source is a time, not a file
            angle_source = str(config.resolve(angle_source))
        found = {"angles_kind": angles.kind, "angles": angle_source, "angle_options": dict(angles.options)}
    assess = config.steps.assess
    slope_aspect, dem, clusters = (None if pattern is None else config.resolve(fill(pattern)) for pattern in (
        config.inputs.slope_aspect, config.inputs.dem, None if assess is None else assess.clusters))
    scene = Scene(name, image, classes, outputs=outputs, slope_aspect=slope_aspect, dem=dem, clusters=clusters,
                  **found)
    action, reason = _action(config, scene)
    scene = dataclasses.replace(scene, action=action, reason=reason)
    return dataclasses.replace(scene, fingerprint=fingerprint(scene, config))


def _output_paths(config: ChainConfig, output_dir: Path, fill, name: str) -> dict[str, Path]:
    naming, steps, outputs = config.outputs, config.steps, {}
    if steps.strata is not None:
        outputs["strata"] = output_dir / fill(naming.strata_naming)
    if steps.correct is not None:
        outputs["corrected"] = output_dir / fill(naming.naming)
        if steps.correct.qa:
            outputs["qa"] = output_dir / fill(naming.qa_naming)
        if naming.uncertainty:
            outputs["uncertainty"] = output_dir / fill(naming.uncertainty_naming)
    if steps.assess is not None:  # the figure's name: brdfcorr.plot.assess.write_assessment_figures
        outputs["assess"] = output_dir / f"{name}_assess.json"
        outputs["assess_profiles"], = figure_paths(output_dir, prefix=f"{name}_assess")
    if steps.quicklook is not None:
        outputs["quicklook"] = output_dir / fill(naming.quicklook_naming)
    return outputs


def _action(config: ChainConfig, scene: Scene) -> tuple[str, str]:
    """(action, reason) from the files alone; :func:`brdfcorr.chain.resume.redo_stale` then checks the
    skipped scenes."""
    missing = [f"{role} {path}" for role, path in scene.inputs() if not path.exists()]
    if missing:
        return "fail", "missing input: " + ", ".join(missing)
    existing = config.outputs.existing
    if scene.outputs and all(path.exists() for path in scene.outputs.values()):
        if existing == "skip":
            return "skip", "complete outputs exist"
        if existing == "error":
            return "fail", "outputs exist (outputs.existing: error)"
    return "run", ""
