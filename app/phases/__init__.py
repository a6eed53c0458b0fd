"""The phases of a run, each a use of the one loop: training (generations of lives and
evolution), the implementation phase, and the live robots the dashboard shows."""
