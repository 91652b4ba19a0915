"""wheelcal — calibrate triaxial accelerometers with a spinning, tilted bicycle wheel.

Layers, one direction (each imports only from those above it):

``model`` (pure numpy) ← ``simulate`` / ``estimate`` ← ``diagnose`` ←
``io`` (MCAP), ``viz`` (Rerun), ``batch``, ``cli``.
"""

__version__ = "0.1.0"
