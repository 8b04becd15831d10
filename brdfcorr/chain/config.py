"""Chain configs: a whole processing run (inputs, parameters, steps, outputs, engine) as YAML.

A chain config makes a run repeatable and reviewable. It is validated with pydantic v2 models
(``extra="forbid"``: a misspelt key is an error, not ignored); errors name the key path and, for
enumerations and unknown keys, the allowed values::

    chain.yaml: engine.scheduler: 'thread' is not allowed; allowed: 'threads', 'processes', ...
    chain.yaml: outputs.compres: unknown key; allowed keys: directory, naming, ...

Relative paths and patterns in a config are relative to the directory of the config file. Per-scene
sources (angles, class map) and outputs are *name patterns* (:mod:`brdfcorr.chain.patterns`).
A commented example of every key is in ``configs/`` (``configs/demo.yaml`` is the chain
``brdfcorr demo`` runs).

This module holds the whole config (:class:`ChainConfig`), its loading and the dotted-key
overrides; the models of its sections are in :mod:`brdfcorr.chain.config_inputs` (``inputs``,
``parameters``), :mod:`brdfcorr.chain.config_steps` (``steps``) and
:mod:`brdfcorr.chain.config_outputs` (``outputs``, ``engine``). Import every name from here.

Example
-------
>>> config = ChainConfig.from_dict({
...     "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": "(?P<scene>.+)_image",
...                "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"},
...                "classes": "{dir}/{scene}_classes.tif"},
...     "parameters": {"materials": {1: "roof_tile"}},
...     "outputs": {"directory": "out"},
... })
>>> config.engine.scheduler, config.outputs.naming
('threads', '{scene}_brdf.tif')
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping
from pathlib import Path

from pydantic import Field, TypeAdapter, ValidationError, model_validator

from brdfcorr._validation import StrictModel, describe_errors
from brdfcorr.chain.config_inputs import AngleKind as AngleKind
from brdfcorr.chain.config_inputs import AngleSource, InputsConfig, ParametersConfig
from brdfcorr.chain.config_outputs import EngineConfig, OutputsConfig
from brdfcorr.chain.config_steps import (
    AssessStep,
    CorrectStep,
    GoniometerFit,
    ImageryFit,
    MeasurementSet,
    QuicklookStep,
    StepsConfig,
    StrataStep,
    TerrainStep,
)
from brdfcorr.chain.config_steps import SurfaceModel as SurfaceModel
from brdfcorr.chain.patterns import PATTERN_FIELDS, format_pattern
from brdfcorr.errors import ConfigError
from brdfcorr.io.files import parse_yaml, read_document
from brdfcorr.io.sensors import flip_refusal
from brdfcorr.params import ParameterTable, ReferenceGeometry
from brdfcorr.params.table import coefficient_table, is_coefficient_name

__all__ = [
    "ChainConfig",
    "ConfigError",
    "InputsConfig",
    "AngleSource",
    "ParametersConfig",
    "ImageryFit",
    "GoniometerFit",
    "MeasurementSet",
    "CorrectStep",
    "TerrainStep",
    "QuicklookStep",
    "AssessStep",
    "StrataStep",
    "StepsConfig",
    "OutputsConfig",
    "EngineConfig",
    "load_config",
    "apply_overrides",
    "format_pattern",
    "PATTERN_FIELDS",
]


class ChainConfig(StrictModel):
    """A whole processing chain. Load with :func:`load_config` (paths relative to the file).

    Attributes
    ----------
    inputs, parameters, reference, steps, outputs, engine :
        See :class:`InputsConfig`, :class:`ParametersConfig`,
        :class:`brdfcorr.params.ReferenceGeometry` (optional: default the table's, else observed
        sun and nadir view), :class:`StepsConfig`, :class:`OutputsConfig`, :class:`EngineConfig`.
    name : str
        A label for the run report.
    base_dir : Path
        Directory relative paths are resolved against (set by :func:`load_config`; not a key).

    Notes
    -----
    The view azimuth convention of the angle sources is one setting: ``inputs.flip_view_azimuth``
    (for a fit-only chain too) or ``steps.correct.flip_view_azimuth``; given at ``inputs`` it is
    the correct step's too, and a correct step that gives the other value is a
    :class:`ConfigError` (:attr:`flips_view_azimuth`).
    """

    name: str = "brdfcorr chain"
    inputs: InputsConfig
    parameters: ParametersConfig = Field(default_factory=ParametersConfig)
    reference: ReferenceGeometry | None = None
    steps: StepsConfig = Field(default_factory=StepsConfig)
    outputs: OutputsConfig
    engine: EngineConfig = Field(default_factory=EngineConfig)

    _base_dir: Path = Path(".")
    _source: str = "chain config"

    @model_validator(mode="before")
    @classmethod
    def _one_view_azimuth_convention(cls, data: object) -> object:
        """``inputs.flip_view_azimuth``, where given, is also the correct step's (so the step, its
        fingerprint and the config written back say what the run does); a correct step that gives
        the other value is refused. Anything else malformed is left to the fields' own checks."""
        if not isinstance(data, Mapping):
            return data
        given = _given_bool(data, "inputs", "flip_view_azimuth")
        steps = data.get("steps", {})
        correct = steps.get("correct", {}) if isinstance(steps, Mapping) else None
        if given is None or not isinstance(correct, Mapping):  # not given; no correct step (null)
            return data
        step = _given_bool(steps, "correct", "flip_view_azimuth")
        if step is None and correct.get("flip_view_azimuth") is not None:  # no boolean: the field says so
            return data
        if step is not None and step != given:
            raise ValueError(f"inputs.flip_view_azimuth is {str(given).lower()} but steps.correct.flip_view_azimuth "
                             f"is {str(step).lower()}: the view azimuth convention of the angle sources is one "
                             "setting, give it once (inputs.flip_view_azimuth)")
        return {**data, "steps": {**steps, "correct": {**correct, "flip_view_azimuth": given}}}

    @model_validator(mode="after")
    def _has_parameters(self) -> ChainConfig:
        if (self.steps.correct is not None and self.parameters.table is None
                and not self.parameters.materials and not self.parameters.classes
                and self.steps.fit is None):
            raise ValueError(
                "the correct step needs a parameter table: set parameters.table, parameters.materials, "
                "parameters.classes or a steps.fit step"
            )
        correct, inputs = self.steps.correct, self.inputs
        has_terrain = inputs.slope_aspect is not None or inputs.dem is not None
        if correct is not None and correct.terrain is not None and not has_terrain:
            raise ValueError("steps.correct.terrain needs slope and aspect: set inputs.slope_aspect or inputs.dem")
        if has_terrain and (correct is None or correct.terrain is None):
            raise ValueError("inputs.slope_aspect and inputs.dem are read by steps.correct.terrain: set it "
                             "(e.g. terrain: {}) or leave the terrain inputs out")
        self._check_class_maps()
        refusal = None if inputs.angles is None else flip_refusal(inputs.angles.kind, self.flips_view_azimuth,
                                                                    "inputs.flip_view_azimuth")
        if refusal is not None:
            raise ValueError(refusal)
        if self.outputs.uncertainty and correct is None:
            raise ValueError("outputs.uncertainty is written by the correct step: it needs steps.correct")
        return self

    @property
    def flips_view_azimuth(self) -> bool:
        """The scenes' view azimuths are stored as seen from the sensor (``inputs.flip_view_azimuth``,
        else ``steps.correct``'s ``flip_view_azimuth``): the imagery fit, the correction and the
        assessment read them alike."""
        if self.inputs.flip_view_azimuth is not None:
            return self.inputs.flip_view_azimuth
        return self.steps.correct is not None and self.steps.correct.flip_view_azimuth

    def _check_class_maps(self) -> None:
        """One source of the class maps: ``inputs.classes``, or ``steps.strata`` deriving them; or
        none, for a built-in coefficient set alone (class 1 over the whole image, as ``brdfcorr nbar``)."""
        inputs, strata, parameters = self.inputs, self.steps.strata, self.parameters
        one_class = (parameters.table is not None and is_coefficient_name(parameters.table)
                     and not parameters.materials and not parameters.classes and self.steps.fit is None)
        if strata is None and inputs.classes is None and not one_class:
            raise ValueError("inputs.classes is missing: give the class maps' name pattern, set steps.strata "
                             "to derive NDVI strata of each image, or name a built-in coefficient set as "
                             "parameters.table alone (one class over the whole image)")
        if strata is not None:
            given = [f"inputs.{key}" for key, unset in (("classes", inputs.classes is None),
                                                        ("align_classes", not inputs.align_classes),
                                                        ("class_lookup", not inputs.class_lookup)) if not unset]
            if given:
                raise ValueError(f"steps.strata derives each scene's class map: leave out {', '.join(given)} "
                                 "(or steps.strata, to use the given maps)")

    @property
    def base_dir(self) -> Path:
        return self._base_dir

    @property
    def source(self) -> str:
        return self._source

    def resolve(self, path: str | os.PathLike) -> Path:
        """A config path made absolute against :attr:`base_dir` (``~`` expanded)."""
        path = Path(os.path.expanduser(str(path)))
        return path if path.is_absolute() else self._base_dir / path

    def table_path(self) -> Path | None:
        """``parameters.table`` resolved (:meth:`resolve`); None where it is unset or names a built-in
        coefficient set (``roy2017``) and no file has that name, as ``brdfcorr correct --params``."""
        name = self.parameters.table
        if name is None:
            return None
        path = self.resolve(name)
        return None if not path.exists() and is_coefficient_name(name) else path

    def given_table(self) -> ParameterTable | None:
        """The table of ``parameters.table`` (a file, or a built-in coefficient set as class 1)."""
        if self.parameters.table is None:
            return None
        path = self.table_path()
        return coefficient_table(self.parameters.table) if path is None else ParameterTable.load(path)

    @classmethod
    def from_dict(cls, data: object, source: str = "chain config", base_dir: str | os.PathLike = ".") -> ChainConfig:
        """Validate a parsed document; :class:`ConfigError` names ``source`` and the key path."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: expected a mapping of sections (inputs, outputs, ...), "
                              f"got {type(data).__name__}")
        try:
            config = cls.model_validate(dict(data))
        except ValidationError as error:
            raise ConfigError(f"{source}: {describe_errors(error, ChainConfig)}") from None
        config._base_dir = Path(base_dir).resolve()
        config._source = source
        return config

    def to_dict(self) -> dict:
        """The config as plain data (JSON/YAML-friendly), defaults filled in."""
        return self.model_dump(mode="json")


_BOOLEAN = TypeAdapter(bool)


def _given_bool(document: object, section: str, key: str) -> bool | None:
    """The value of ``section.key`` in a raw ``document``, read as the field reads it (YAML's
    ``true``, pydantic's ``"yes"``, ...); None where it is not given, null or no boolean (which the
    field itself then refuses)."""
    part = document.get(section) if isinstance(document, Mapping) else None
    value = part.get(key) if isinstance(part, Mapping) else None
    if value is None:
        return None
    try:
        return _BOOLEAN.validate_python(value)
    except ValidationError:
        return None


def load_config(path: str | os.PathLike, overrides: Mapping[str, object] | None = None) -> ChainConfig:
    """Read and validate a chain config (YAML, ``yaml.safe_load``).

    Parameters
    ----------
    path : path-like
        The config file; its directory is the base of relative paths.
    overrides : mapping of str to object, optional
        Dotted keys replaced before validation (``{"engine.workers": 2}``), see
        :func:`apply_overrides`.

    Raises
    ------
    ConfigError
        Unreadable file (also: not a regular file, larger than
        :data:`brdfcorr.io.files.MAX_DOCUMENT_BYTES`, not UTF-8), invalid YAML (with line and
        column) or invalid content (key path and allowed values).
    """
    path = Path(path)
    data = parse_yaml(read_document(path, "chain config", ConfigError), str(path), ConfigError)
    return config_from_document(data, path, overrides)


def config_from_document(
    data: object, path: str | os.PathLike, overrides: Mapping[str, object] | None = None
) -> ChainConfig:
    """Validate the parsed YAML ``data`` of the chain config file ``path`` (see :func:`load_config`)."""
    path = Path(path)
    if data is None:
        data = {}
    if overrides:
        data = apply_overrides(data, overrides, source=str(path))
    return ChainConfig.from_dict(data, source=str(path), base_dir=path.parent)


def apply_overrides(data: object, overrides: Mapping[str, object], source: str = "chain config") -> dict:
    """A copy of ``data`` with dotted keys set (``"engine.workers"``), creating sections as needed."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a mapping of sections, got {type(data).__name__}")
    result = copy.deepcopy(dict(data))
    for key, value in overrides.items():
        parts = [part for part in str(key).split(".") if part]
        if not parts:
            raise ConfigError(f"override {key!r}: empty key")
        node = result
        for depth, part in enumerate(parts[:-1]):
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                raise ConfigError(f"override {key!r}: {'.'.join(parts[:depth + 1])} is not a section")
            node = child
        node[parts[-1]] = value
    return result
