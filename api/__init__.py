"""The composition root: the ``calbench`` CLI, the FastAPI service and dashboard, the run
runner, certificates and the drift scheduler.

Layer rule: the top layer; it may import every other package, and none imports it.
"""
