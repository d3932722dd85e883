"""Experiments: training, imitation and evaluation — the machinery behind ``train.py``,
``imitate.py`` and ``evaluate.py``. Nothing outside this package imports it.
"""
