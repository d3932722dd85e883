"""Policies: every agent behind the one ``predict()`` interface (classical baselines, learned
models) and the registry that builds them. Running a policy never imports training code.
"""
