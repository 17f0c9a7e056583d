"""Regression testing by replay: tolerance rules, field-by-field comparison of decoded messages, reports.

Pure logic on decoded messages (dicts, lists, numpy arrays); reading recordings is `bus.diff`'s job.
"""
