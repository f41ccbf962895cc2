"""View-selection methods behind one interface: ``policy(state) -> view | [views]``.

* :mod:`~nbv.policies.episode`: the episode state, running an episode, coverage curves, AUC.
* :mod:`~nbv.policies.baselines`: random and the oracle.
* :mod:`~nbv.policies.network`: a trained PCNBV / PCNBV-sph checkpoint.
* :mod:`~nbv.policies.hull_sco`: the convex-hull planner, one-shot or replanned.
* :mod:`~nbv.policies.inputs`: the cloud and signature a policy computes, with their times.
* :mod:`~nbv.policies.registry`: the one list of methods: name, needs, checks, style, builder.

Every policy but the oracle reads only what the captured views saw and the camera poses. Each
records the seconds of every decision in ``timings`` (stage -> list of seconds) and what it had to
work around in ``notes``.
"""
