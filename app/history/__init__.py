"""What a station did, read back from its audit log: runs, the timeline of each, and an
operator's "done today"."""
