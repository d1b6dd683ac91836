"""rig: control and acquisition software for image-based BRDF goniophotometers."""

__version__ = "0.1.0"
