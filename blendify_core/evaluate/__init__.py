"""Evaluation: comparing results (:mod:`.compare`), tolerance tiers, statistics and cross-checks."""
