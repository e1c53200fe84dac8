"""Generators, Sec. III-C and Table II: networks, rectified flow and DDPM, the method registry and the
public sampler (``jg.sample``)."""
