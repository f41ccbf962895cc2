"""Training of PCNBV and PCNBV-sph: ``python -m train fold=3 score=vig model=pcnbv_sph``."""
