"""Onboarding a new device: drafting a map from its manual (``drivemap draft``)."""
