"""Pieces shared by every MAST model: parameter schema and the Block base."""
