"""Headless previews of a SimCache: contact sheets, GIF/MP4 animations and plots.

``api`` (the entry point), ``options`` (argument parsing), ``camera``
(scene, automatic and explicit pinhole cameras), ``geometry`` (what is drawn
per frame), ``raster`` (the numba z-buffer rasteriser), ``render`` (a frame),
``sheet`` (labels and contact sheets), ``writers`` (PNG, GIF, MP4) and
``plots`` (matplotlib figures, e.g. the blast calculator's curves). Nothing
heavy is imported here, so the CLI starts fast.
"""
