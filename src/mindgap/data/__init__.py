"""Plain pytrees of experience that every learner shares: transitions, replay, segments, preferences.

The bottom layer: it imports nothing else of mindgap, so worlds, models, teachers and
learners can all build on it.
"""
