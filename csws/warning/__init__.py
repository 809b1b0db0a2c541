"""Decides the curve speed warning of clauses 5 and 6: levels, target CPOI, HMI, and when a level goes off."""
