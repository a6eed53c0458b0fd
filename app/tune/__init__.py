"""`gnp-lab tune`: Optuna studies of a brain's settings on a Gymnasium task.

`space` declares what is searched and the tuning seeds (no Optuna), `study` runs a study's
trials in its storage file, `publish` and `preset` write and read the preset a study leaves;
the command is app/cli/tune.py. Importing the package imports none of them.
"""
