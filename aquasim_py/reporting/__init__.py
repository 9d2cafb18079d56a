"""What draws and tabulates results: the reports, their plots and tables, and how numbers print.

One module per thing reported:

- :mod:`.report`: ``aquasim-py report DIR``: the plots and one ``report.html`` of a run's, a
  variants run's or a sweep's output directory;
- :mod:`.variants`: the cross-variant page of a variants run;
- :mod:`.sweep`: each metric against each swept value;
- :mod:`.environment`: a range-dependent run's section with the rays of one link;
- :mod:`.tables`: the tables a run, a variants run and a sweep print and show;
- :mod:`.display`: a human unit per metric, short numbers, tables that fit a terminal;
- :mod:`.intervals`: confidence intervals over Monte Carlo runs that respect a metric's sign;
- :mod:`.figures`: what every plot shares (matplotlib's file-only backend, DPI, saving).

Nothing here runs a simulation: everything is drawn from what a run wrote.
"""
