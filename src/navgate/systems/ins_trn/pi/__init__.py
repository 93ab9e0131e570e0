"""Seed 000's Raspberry Pi 5: the TRN service (terrain, correlators) behind the link."""
