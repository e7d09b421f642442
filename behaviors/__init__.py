"""py_trees behaviours of the landing mission and the tree builder.

Behaviours reach the vehicle only through the ports declared in :mod:`behaviors.ports`
and read time only from the injected clock; this package never imports :mod:`autonomy`.
"""
