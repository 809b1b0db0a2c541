"""``csws sweep``: fleet studies of many co-simulations (factors x seeds) on Dask, with their summary."""
