"""``python -m nbv.synthetic preview=out.png``: the contact sheet of the synthetic shapes.

The shapes and the drawing live in :mod:`nbv.assets.synthetic`; this package holds the command:
its settings (:mod:`nbv.synthetic.config`, ``conf/synthetic.yaml``) and its main.
"""
