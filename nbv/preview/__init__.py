"""``python -m nbv.preview preview=out.png``: the contact sheet of the synthetic shapes.

The shapes and the drawing live in :mod:`nbv.assets.synthetic`; this package holds the command:
its settings (:mod:`nbv.preview.config`, ``conf/preview.yaml``) and its main.

Third-party imports: none.
"""
