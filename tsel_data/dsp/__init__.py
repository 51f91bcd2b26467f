"""Signal processing with no knowledge of rooms or scenes: FFT sizes and real FFTs
(``fft``, ``realfft``), the time-varying renderer for moving sources (``timevarying``, with
the direct path it moves between knots, ``delaypath``, and its stored fractional-delay
filters, ``farrow_table``), and features for trainers (``features``: GCC-PHAT, spectra).

Import order: ``fft``, ``realfft``, ``farrow_table``, ``features``; ``delaypath`` uses
``fft`` and ``farrow_table``; ``timevarying`` and ``hardware`` (microphones as built,
applied to audio) use ``delaypath``.
"""
