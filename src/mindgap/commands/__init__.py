"""Sub-commands of the ``mindgap`` CLI that live in their own modules."""
