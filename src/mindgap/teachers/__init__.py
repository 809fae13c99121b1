"""Internal: simulated people (ratings, preferences, expectations) and host teachers (real people).

The ones a user passes to a learner are reachable from the public modules
(:func:`mindgap.eps.person`, ``teacher="biased"`` / ``"true"``, :class:`~mindgap.RatingTeacher`).
"""
