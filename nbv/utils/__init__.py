"""Helpers every layer may use: crash-safe writes, generators derived from names, bit counts."""
