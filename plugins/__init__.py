"""Built-in ltc plugins, registered through the ``ltc`` entry-point group like any other."""
