"""The map: the object table and its index (model), the HDF5 store, query, export and render."""
