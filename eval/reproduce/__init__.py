"""Reproductions of the seed papers' numerical studies (``fawtgym reproduce <name>``)."""
