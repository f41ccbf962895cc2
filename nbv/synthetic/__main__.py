"""``python -m nbv.synthetic --preview out.png [--seed S] [--per-category K] [--tile T]``."""

from nbv.assets.synthetic.preview import main

if __name__ == "__main__":
    raise SystemExit(main())
