"""The pieces every entry point's configuration shares (imports only omegaconf and hydra).

- :mod:`nbv.config.settings`: one declaration per setting. A frozen settings dataclass, nested
  like its YAML, names each key, its type, default and allowed range; :class:`Entry` derives the
  hydra schema from it and builds the settings from a composed config (errors name the key path).
- :mod:`nbv.config.schema`: :class:`ConfigError`, the shared groups of ``conf/``
  (:class:`CameraConfig`, :class:`ProtocolConfig`, :class:`PathsConfig`), :func:`validated` (a
  config checked against a schema), :func:`describe` (a hydra or OmegaConf error as one line) and
  :func:`check_views` (view indices inside a viewspace).
- :mod:`nbv.config.cli`: :func:`command` builds every entry point: hydra composes its config, a
  refused config or setting ends with one line on stderr, exit status 2 and no run folder.

The range rules themselves (:func:`nbv.utils.fields.setting`) live below this layer, so that the
library's own settings (the planners', the occupancy map's) declare theirs the same way. Each
entry point's settings live beside it (``nbv/dataset/config.py``, ``train/config.py``,
``nbv/eval/config.py``, ...); ``conf/*.yaml`` only override a default or interpolate a shared
group; ``docs/configuration.md`` lists every key (``python scripts/config_reference.py``).

Third-party imports: hydra, omegaconf.
"""
