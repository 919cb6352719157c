"""The bad-input corpus (issue 8): see corpus.py; OUTCOMES.md is written by make_outcomes.py."""
