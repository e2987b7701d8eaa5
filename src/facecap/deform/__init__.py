"""deform subpackage."""
