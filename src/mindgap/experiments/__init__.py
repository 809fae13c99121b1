"""The dissertation's experiments behind ``mindgap reproduce NAME`` (internal; run them from the command line)."""
