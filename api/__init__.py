"""The interface: the ``calbench`` CLI, the FastAPI service (routes, schemas, request guard,
authentication, document cache) and the dashboard, and the composition root that builds them
from the settings. What runs the bench is :mod:`station`.

Layer rule: the top layer; it may import every other package, and none imports it.
"""
