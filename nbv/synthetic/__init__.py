"""``python -m nbv.synthetic --preview out.png``: the contact sheet of the synthetic shapes.

The shapes live in :mod:`nbv.assets.synthetic`; this package only keeps the command's name
(see :func:`nbv.assets.synthetic.preview.main` for its options).
"""
