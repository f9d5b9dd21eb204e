"""Benchmarks: rays/s and samples/s (:mod:`.throughput`), error against time (:mod:`.convergence`) and
the Mitsuba 3 comparison (:mod:`.mitsuba_export`, :mod:`.mitsuba_runner`).
"""
