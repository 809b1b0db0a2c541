"""The csws HTTP service: a FastAPI app that adapts HTTP to the csws library."""
