"""The lab's plumbing: worker processes, safe file names, exit codes."""
