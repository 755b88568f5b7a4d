"""Raw time series → sensitivity and robustness figures (docs/domain.md §8,
docs/interfaces.md §2, §5).

Pure numpy/scipy.  Modules: ``records`` (readers, validation), ``sinefit`` (IEEE 1057
three-/four-parameter fits, rate estimate), ``paper`` (the study's scan and filters),
``measure`` (amplitudes by method), ``linear`` / ``curvilinear`` (the benches),
``budget`` (GUM budget), ``sensitivity`` (entry point), ``snr`` (MATLAB ``snr``),
``robustness`` (RR, SR, before/after), ``synthetic`` (records of known truth).
"""
