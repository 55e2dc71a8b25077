"""Reproductions of individual papers beyond the benchmark tables (each a ``python -m`` module).

``python -m benchmarks.studies.alanwar2022 --out reports/datadriven.md``: the data-driven
observers of Alanwar, Berndt, Johansson, Sandberg (ECC 2022).
"""
