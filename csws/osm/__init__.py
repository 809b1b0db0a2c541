"""OpenStreetMap import: netconvert with options that keep curve geometry, plus a curve index."""
