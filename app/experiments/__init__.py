"""Experiments: arms × seeds × implementation conditions, on Dask, with statistics."""
