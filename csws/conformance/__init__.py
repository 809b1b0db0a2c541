"""The test procedure of T/ITS 0091-2018 clause 7.5, run in SUMO and judged per clause 7.6."""
