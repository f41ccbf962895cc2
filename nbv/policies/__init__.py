"""View-selection methods behind one interface: ``policy(state) -> view | [views]``.

* :mod:`~nbv.policies.episode`: the episode state, running an episode, coverage curves, AUC.
* :mod:`~nbv.policies.reference`: random, spread and the oracle.
* :mod:`~nbv.policies.network`: a trained PCNBV / PCNBV-sph checkpoint.
* :mod:`~nbv.policies.setcover`: the convex-hull planner, one-shot or replanned.
* :mod:`~nbv.policies.inputs`: the cloud and signature a policy computes, with their times.
* :mod:`~nbv.policies.registry`: the one table of methods: name, needs, checks, builder.
* :mod:`~nbv.policies.method`: what a method is (:class:`~nbv.policies.method.Method`) and what
  building its policy may use (:class:`~nbv.policies.method.MethodContext`).
* :mod:`~nbv.policies.builders`: how each method builds its policy for one episode.

Every policy but the oracle reads only what the captured views saw and the camera poses. Each
records the seconds of every decision in ``timings`` (stage -> list of seconds) and what it had to
work around in ``notes``.

The other modules:

* :mod:`~nbv.policies.completion`: Planners with a shape prior: the captured cloud completed, then
  planned on.
* :mod:`~nbv.policies.conditioned_network`: The viewspace-conditioned network
  (:mod:`nbv.models.view_conditioned`) as a view-selection policy.
* :mod:`~nbv.policies.hybrid`: The convex-hull plan while it covers, then volumetric information
  gain.
* :mod:`~nbv.policies.learned_gain`: ``ig_learned``: the occupancy map of ``ig``, with candidates
  ranked by a learned score.
* :mod:`~nbv.policies.lockstep`: Episodes of one model stepped together, so that a network decides
  for all of them at once.
* :mod:`~nbv.policies.two_stage`: The two-stage planner of "Spherical Harmonics for Robust
  Next-best-view Estimation": a network trained on VIG picks the first views, then the convex-hull
  set cover plans the rest.
* :mod:`~nbv.policies.view_matching`: A PCNBV network on another viewspace than the one it was
  trained on, its views matched by direction.
* :mod:`~nbv.policies.infogain`: Volumetric information gain: the classical generate-and-test
  next-best view on an occupancy map.

Third-party imports: numpy, open3d, scipy, torch.
"""
