"""Numerics of whole piles (the workflow's target ``numerics_piles``): how precise
a pile's observables and the ensemble's results are against what they cost.

``pile_precision``  error of pile observables against run time
``ensemble_cost``   standard error of the headline results against compute time
``piles_report``    their Markdown tables
``figures``         their figures
``command``         their ``data`` / ``figure`` command lines

The run times they read come from :mod:`analysis.run_times`, the product's
reporting of what a job cost (``python -m analysis run-times``).
"""
