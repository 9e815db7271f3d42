"""JSON Schemas of every file format ltc reads or writes."""
