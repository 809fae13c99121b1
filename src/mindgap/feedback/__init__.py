"""Internal: demonstrations, ratings files and query selection for the learners."""
