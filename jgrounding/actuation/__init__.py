"""Actuation representation, Sec. III-B: uniform Catmull-Rom splines over the tendon commands."""
