"""Onboarding a new device: draft a map from a manual, import definitions users own, probe a live device."""
