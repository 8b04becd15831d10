"""Config-driven processing chains over many scenes, built on :mod:`brdfcorr.tasks`.

- :mod:`~brdfcorr.chain.config` (with ``config_inputs``, ``config_outputs``, ``config_steps``) and
  :mod:`~brdfcorr.chain.patterns`: chain configs and their per-scene name patterns;
- :mod:`~brdfcorr.chain.plan`, :mod:`~brdfcorr.chain.run`, :mod:`~brdfcorr.chain.report`,
  :mod:`~brdfcorr.chain.quicklook`: plan, run and report a chain;
- :mod:`~brdfcorr.chain.api`: ``brdfcorr.run_chain`` (a config file or a loaded config);
- :mod:`~brdfcorr.chain.demo`: the demo scene and its run.
"""

#: The chain modules, imported at first use as ``brdfcorr.chain.<name>``.
__all__ = ["api", "config", "config_inputs", "config_outputs", "config_steps", "demo", "patterns", "plan",
           "quicklook", "report", "run"]
