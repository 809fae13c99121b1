"""Design checks of worlds: whether a world can show what a method claims, by exact planning and the simulated person.

* :mod:`~.terrain_check`: plan a terrain world under the truth and under the person's belief, roll
  both out, and test the world file's ``[expect]`` entries (``mindgap worlds plan``);
* :mod:`~.design_check`: whether a world's preferences identify the person's belief, and what an
  unaware learner loses (``mindgap design check``);
* :mod:`~.belief_fit`: the maximum-likelihood fit of the belief from simulated answers that the
  design check and the belief-recovery check stand on.

They consult the simulated person (:mod:`mindgap.teachers`) and the planners
(:mod:`mindgap.planning`), so they sit above both.
"""
