"""Diagnosis: find what the model lacks from measured data (residual analysis, effect library)."""
