"""Built-in observer plugins, one module per technique family.

Every module in this package is imported by the registry on first use; its classes register
themselves with :func:`observers.register`.
"""
