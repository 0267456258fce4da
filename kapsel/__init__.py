"""kapsel-py: the extended KAPSEL simulator (kapsel_u2m) in Python."""
__version__ = "0.1.0"
