"""The chain entry of the top-level namespace: ``brdfcorr.run_chain(path)``.

:func:`brdfcorr.chain.run.run_chain` takes a loaded :class:`~brdfcorr.chain.config.ChainConfig`;
this one also takes the config file, as ``brdfcorr run CHAIN.yaml`` does.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from brdfcorr.chain import run as _chain
from brdfcorr.chain.config import ChainConfig, load_config
from brdfcorr.chain.report import RunReport

__all__ = ["run_chain"]


def run_chain(config: ChainConfig | str | os.PathLike, *, overrides: Mapping[str, object] | None = None,
              progress: _chain.Progress | None = None) -> RunReport:
    """Run a chain config over all its scenes and write its run report, as ``brdfcorr run`` does.

    Parameters
    ----------
    config : path-like or ChainConfig
        The chain config file (YAML; relative paths are relative to it), or a config loaded with
        :func:`brdfcorr.chain.config.load_config`.
    overrides : mapping of str to object, optional
        Dotted keys to replace (``{"engine.workers": 2}``), as ``brdfcorr run --set``; only with a
        path (pass them to ``load_config`` otherwise).
    progress : callable, optional
        ``progress(event, info)`` (:mod:`brdfcorr.chain.run`).

    Returns
    -------
    RunReport
        ``report.ok`` is False when a scene failed; ``report.path`` is the JSON report written.

    Raises
    ------
    BrdfcorrError
        Before any scene runs: a bad config, no inputs, a bad parameter table, a failed fit step.
        Failures of single scenes do not raise; they are in the report.
    """
    if isinstance(config, ChainConfig):
        if overrides:
            raise TypeError("overrides apply to a config file; give them to load_config for a loaded config")
    else:
        config = load_config(config, overrides)
    return _chain.run_chain(config, progress=progress)
