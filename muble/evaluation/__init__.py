"""Evaluating an agent over a dataset split: per-episode execution, the results table, plots and reports."""
