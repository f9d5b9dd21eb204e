"""Rendering: settings, film, light tables, the wavefront driver, several devices, Dask, checkpoints and the
``render``/``render_full`` API.
"""
