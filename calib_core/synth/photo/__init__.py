"""Photographic effects (shadows, highlights, markings, blur) and the held-out photographic kinds."""
