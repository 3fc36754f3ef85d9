"""The layout of scenario ids: trainers draw ids below ``EVAL_FIRST_SCENARIO``, evaluations
start there, so no evaluation scenario is ever trained on (``ata.training.TRAINING_ID_LIMIT`` is
this same number)."""

EVAL_FIRST_SCENARIO = 2 ** 40
"""The first scenario id of every evaluation."""
