"""The pieces every entry point's structured config shares (imports only omegaconf and hydra).

- :mod:`nbv.config.schema`: :class:`ConfigError`; the dataclasses of the shared groups of
  ``conf/`` (:class:`CameraConfig`, :class:`ProtocolConfig`, :class:`PathsConfig`);
  :func:`register` (a schema into hydra's ConfigStore), :func:`schema_of` (a schema from a
  settings dataclass), :func:`validated` (a config checked against its schema, with errors
  that name the key path), :func:`describe` (a hydra or OmegaConf error as one line) and
  :func:`check_views` (view indices inside a viewspace).
- :mod:`nbv.config.cli`: :func:`entry_point` (a ``@hydra.main`` function as a command: a refused
  config ends with one line on stderr and exit status 2) and :func:`refuse` (the same inside the
  task, and the run folder hydra made for it removed).

Each entry point's own schema lives beside it: ``nbv/dataset/config.py``, ``train/config.py``,
``nbv/eval/config.py``, ``nbv/bench/config.py``. The values live in ``conf/*.yaml``; the
schemas only say which keys exist and what type each one has.
"""
