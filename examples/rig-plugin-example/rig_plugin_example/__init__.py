"""Example driver plug-in for rig (see this folder's README.md)."""
