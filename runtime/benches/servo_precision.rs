//! Precision side by side on the simulated servo axis: dynid's `identify` with the
//! defaults (and with the highest corner raised to the band where the encoder stands above
//! its noise floor, `to noise floor` and `chains 2-step nf`, capped at a fifth of the
//! Nyquist frequency) against the two classical regressions of [`dynid_runtime::baseline`] on the
//! same records — IDIM-LS (zero-phase Butterworth at 100 Hz, order 4, decimation 5, rows
//! at rest below 1 mm/s dropped; classical and Newey–West standard errors) and SVF-LS
//! (causal fourth-order state-variable filter at 10 Hz and 80 Hz, Newey–West errors; at
//! 80 Hz also with the encoder's rounding compensated, with the rows near rest dropped, and
//! with both).
//!
//! The axis is that of `tests/servo.rs`: m = 50 kg, fv = 120 N·s/m, fc = 15 N,
//! f0 = −2 N, 1 kHz for 25 s, 1 µm encoder, PD controller updated ten times per sample,
//! position and force only (the velocity is not recorded). Each record kind
//! ([`Trajectory`]) is made by [`record`]; per method and parameter the table gives, over
//! the seeds, the RMS relative error, the mean reported standard error (relative), the
//! coverage (fraction of seeds with |error| < 2 SE) and the RMS of error / SE (1 for honest
//! errors), and the mean time per record.
//!
//! Run: `cargo bench -p dynid-runtime --bench servo_precision` (`-- --json` prints one JSON
//! object instead of the table; `DYNID_BENCH_SEEDS=12` sets the number of seeds, 1…N).
//!
//! Measured (2026-11-27, after the input delay was added; seeds 1–12;
//! `DYNID_BENCH_SEEDS=12 cargo bench -p dynid-runtime --bench servo_precision` — on a
//! machine shared with other builds, so `ms/rec` is only roughly comparable within the
//! table; RMS error and mean SE in % of the truth, `cover` the fraction of seeds
//! with |error| < 2 SE, `e/SE` the RMS of error / SE; the planned records carry white noise
//! of 1 % of the force's spread on the force, drawn from the seed — without it every seed
//! would give the same record). Every row but the `--input-delay` and `filtered + delay`
//! ones is that of the previous run to the last digit but for `ms/rec`.
//! `DYNID_BENCH_METHODS=filtered,IDIM` runs only the methods whose names hold one of the comma-separated parts;
//! `DYNID_BENCH_INPUT_OVERSAMPLE=N` sets the controller's updates per sample (10 here):
//!
//! ```text
//! servo axis, seeds 1–12: RMS error, mean SE (both % of the truth), coverage |e| < 2 SE, RMS e/SE
//!
//! random reference
//! method                  param   RMS err   mean SE   cover    e/SE    ms/rec
//! dynid (defaults)            m    0.014%    0.022%    100%    0.68       8.4
//! dynid (defaults)            d    0.472%    0.510%    100%    0.83       8.4
//! dynid (defaults)            r    1.359%    1.388%    100%    0.81       8.4
//! dynid (defaults)           f0    1.465%    0.982%    100%    1.00       8.4
//! dynid --column-chains       m    0.042%    0.031%    100%    1.16       9.9
//! dynid --column-chains       d    0.256%    0.228%     92%    0.96       9.9
//! dynid --column-chains       r    0.702%    0.582%     92%    1.18       9.9
//! dynid --column-chains      f0    0.864%    1.003%     92%    0.80       9.9
//! dynid chains, 2-step        m    0.013%    0.010%     83%    2.06       8.8
//! dynid chains, 2-step        d    0.200%    0.109%     67%    3.65       8.8
//! dynid chains, 2-step        r    0.545%    0.301%     50%    2.92       8.8
//! dynid chains, 2-step       f0    1.179%    0.649%     67%    2.11       8.8
//! dynid to noise floor        m    0.180%    0.143%    100%    0.84       5.7
//! dynid to noise floor        d    1.863%    1.775%    100%    0.69       5.7
//! dynid to noise floor        r    5.029%    4.843%    100%    0.74       5.7
//! dynid to noise floor       f0    2.051%    2.426%     92%    1.10       5.7
//! dynid chains 2-step nf      m    0.012%    0.013%     83%    1.46       7.5
//! dynid chains 2-step nf      d    0.194%    0.207%    100%    1.06       7.5
//! dynid chains 2-step nf      r    0.599%    0.603%     92%    1.15       7.5
//! dynid chains 2-step nf     f0    0.890%    1.134%     92%    1.14       7.5
//! dynid --keep-rests          m    0.014%    0.022%    100%    0.68       4.8
//! dynid --keep-rests          d    0.472%    0.510%    100%    0.83       4.8
//! dynid --keep-rests          r    1.359%    1.388%    100%    0.81       4.8
//! dynid --keep-rests         f0    1.465%    0.982%    100%    1.00       4.8
//! dynid --filtered-eq.        m    0.009%    0.004%     42%    2.41       5.8
//! dynid --filtered-eq.        d    0.152%    0.023%      0%    6.93       5.8
//! dynid --filtered-eq.        r    0.091%    0.053%     75%    1.74       5.8
//! dynid --filtered-eq.       f0    0.091%    0.218%    100%    0.40       5.8
//! dynid filtered 20 Hz        m    0.021%    0.005%      0%    4.33       5.4
//! dynid filtered 20 Hz        d    0.168%    0.024%      0%    7.24       5.4
//! dynid filtered 20 Hz        r    0.189%    0.062%     25%    3.06       5.4
//! dynid filtered 20 Hz       f0    0.099%    0.224%    100%    0.43       5.4
//! dynid filtered 160 Hz       m    0.126%    0.004%      0%   28.92       5.7
//! dynid filtered 160 Hz       d    0.126%    0.021%      0%    5.96       5.7
//! dynid filtered 160 Hz       r    0.059%    0.053%     92%    1.14       5.7
//! dynid filtered 160 Hz      f0    0.098%    0.223%    100%    0.42       5.7
//! dynid --input-delay         m    0.022%    0.022%     83%    1.20       5.1
//! dynid --input-delay         d    0.502%    0.457%     92%    0.97       5.1
//! dynid --input-delay         r    1.308%    1.253%    100%    0.74       5.1
//! dynid --input-delay        f0    0.688%    0.781%     92%    1.05       5.1
//! dynid filtered + delay      m    0.005%    0.004%     83%    1.23       6.0
//! dynid filtered + delay      d    0.005%    0.004%     92%    1.36       6.0
//! dynid filtered + delay      r    0.010%    0.009%     92%    1.10       6.0
//! dynid filtered + delay     f0    0.069%    0.090%    100%    0.81       6.0
//! dynid filt.+delay 500/s      m    0.007%    0.003%     42%    2.24       7.3
//! dynid filt.+delay 500/s      d    0.007%    0.004%     67%    1.81       7.3
//! dynid filt.+delay 500/s      r    0.009%    0.009%     83%    1.05       7.3
//! dynid filt.+delay 500/s     f0    0.065%    0.084%    100%    0.83       7.3
//! IDIM-LS, OLS errors         m    0.029%    0.016%     75%    1.79       1.7
//! IDIM-LS, OLS errors         d    0.163%    0.088%     58%    1.77       1.7
//! IDIM-LS, OLS errors         r    0.785%    0.197%      0%    3.96       1.7
//! IDIM-LS, OLS errors        f0    0.639%    0.872%     92%    0.73       1.7
//! IDIM-LS, HAC errors         m    0.029%    0.014%     67%    2.08       1.7
//! IDIM-LS, HAC errors         d    0.163%    0.064%     50%    2.41       1.7
//! IDIM-LS, HAC errors         r    0.785%    0.169%      0%    4.61       1.7
//! IDIM-LS, HAC errors        f0    0.639%    0.587%     92%    1.03       1.7
//! SVF-LS 10 Hz, HAC           m    0.102%    0.022%      0%    4.63     151.9
//! SVF-LS 10 Hz, HAC           d    0.169%    0.102%     83%    1.70     151.9
//! SVF-LS 10 Hz, HAC           r    0.681%    0.275%     50%    1.99     151.9
//! SVF-LS 10 Hz, HAC          f0    1.210%    1.556%    100%    0.74     151.9
//! SVF-LS 80 Hz, HAC           m    0.027%    0.006%      0%    4.45      22.8
//! SVF-LS 80 Hz, HAC           d    0.096%    0.037%     33%    3.41      22.8
//! SVF-LS 80 Hz, HAC           r    0.149%    0.094%     92%    1.48      22.8
//! SVF-LS 80 Hz, HAC          f0    0.313%    0.417%    100%    0.62      22.8
//! SVF-LS 80 Hz, EIV comp.      m    0.034%    0.006%      0%    5.58      21.7
//! SVF-LS 80 Hz, EIV comp.      d    0.096%    0.037%     33%    3.40      21.7
//! SVF-LS 80 Hz, EIV comp.      r    0.149%    0.094%     92%    1.47      21.7
//! SVF-LS 80 Hz, EIV comp.     f0    0.314%    0.416%    100%    0.62      21.7
//! SVF-LS 80 Hz, rests out      m    0.007%    0.005%     83%    1.54      20.5
//! SVF-LS 80 Hz, rests out      d    0.149%    0.025%      0%    5.95      20.5
//! SVF-LS 80 Hz, rests out      r    0.076%    0.059%     92%    1.30      20.5
//! SVF-LS 80 Hz, rests out     f0    0.097%    0.256%    100%    0.39      20.5
//! SVF-LS 80, rests+EIV        m    0.014%    0.005%      8%    2.95      20.6
//! SVF-LS 80, rests+EIV        d    0.151%    0.025%      0%    5.99      20.6
//! SVF-LS 80, rests+EIV        r    0.079%    0.059%     92%    1.34      20.6
//! SVF-LS 80, rests+EIV       f0    0.096%    0.255%    100%    0.38      20.6
//!
//! planned moves
//! method                  param   RMS err   mean SE   cover    e/SE    ms/rec
//! dynid (defaults)            m    0.027%    0.038%    100%    0.75      24.1
//! dynid (defaults)            d    0.129%    0.166%     92%    0.85      24.1
//! dynid (defaults)            r    0.210%    0.242%     92%    0.93      24.1
//! dynid (defaults)           f0    0.239%    0.309%    100%    0.83      24.1
//! dynid --column-chains       m    0.071%    0.047%     83%    1.52      25.1
//! dynid --column-chains       d    0.477%    0.208%     42%    2.21      25.1
//! dynid --column-chains       r    0.689%    0.293%     42%    2.28      25.1
//! dynid --column-chains      f0    0.219%    0.427%     92%    0.71      25.1
//! dynid chains, 2-step        m    0.070%    0.028%     42%    2.60      25.0
//! dynid chains, 2-step        d    0.205%    0.144%     83%    1.63      25.0
//! dynid chains, 2-step        r    0.290%    0.205%     92%    1.50      25.0
//! dynid chains, 2-step       f0    0.231%    0.352%    100%    0.71      25.0
//! dynid to noise floor        m    0.053%    0.014%      8%    5.49      23.6
//! dynid to noise floor        d    0.359%    0.158%     33%    2.29      23.6
//! dynid to noise floor        r    0.395%    0.233%     75%    1.66      23.6
//! dynid to noise floor       f0    0.236%    0.421%    100%    0.61      23.6
//! dynid chains 2-step nf      m    0.034%    0.098%     92%    0.86      25.9
//! dynid chains 2-step nf      d    0.414%    0.845%    100%    0.55      25.9
//! dynid chains 2-step nf      r    0.501%    0.907%    100%    0.70      25.9
//! dynid chains 2-step nf     f0    0.342%    3.824%    100%    0.11      25.9
//! dynid --keep-rests          m   23.417%    2.846%      0%    8.23      22.9
//! dynid --keep-rests          d   67.303%    6.899%      0%   36.85      22.9
//! dynid --keep-rests          r   67.263%   11.077%      0%    6.07      22.9
//! dynid --keep-rests         f0    6.922%   20.803%    100%    0.33      22.9
//! dynid --filtered-eq.        m    0.009%    0.009%     92%    0.95      23.4
//! dynid --filtered-eq.        d    0.207%    0.042%      0%    5.13      23.4
//! dynid --filtered-eq.        r    0.105%    0.063%     67%    1.66      23.4
//! dynid --filtered-eq.       f0    0.305%    0.338%    100%    0.94      23.4
//! dynid filtered 20 Hz        m    0.011%    0.021%    100%    0.53      23.0
//! dynid filtered 20 Hz        d    0.129%    0.050%     25%    2.63      23.0
//! dynid filtered 20 Hz        r    0.065%    0.073%    100%    0.92      23.0
//! dynid filtered 20 Hz       f0    0.388%    0.358%     92%    1.09      23.0
//! dynid filtered 160 Hz       m    0.172%    0.012%      0%   14.49      23.5
//! dynid filtered 160 Hz       d    0.210%    0.041%      0%    5.36      23.5
//! dynid filtered 160 Hz       r    0.124%    0.061%     67%    2.01      23.5
//! dynid filtered 160 Hz      f0    0.278%    0.352%    100%    0.81      23.5
//! dynid --input-delay         m    0.042%    0.029%     75%    1.50      23.2
//! dynid --input-delay         d    0.218%    0.245%     92%    0.97      23.2
//! dynid --input-delay         r    0.257%    0.333%    100%    0.83      23.2
//! dynid --input-delay        f0    0.232%    0.320%    100%    0.81      23.2
//! dynid filtered + delay      m    0.008%    0.012%    100%    0.74      24.1
//! dynid filtered + delay      d    0.050%    0.056%    100%    0.83      24.1
//! dynid filtered + delay      r    0.060%    0.070%    100%    0.85      24.1
//! dynid filtered + delay     f0    0.319%    0.318%     92%    1.06      24.1
//! dynid filt.+delay 500/s      m    0.015%    0.009%     92%    1.63      20.3
//! dynid filt.+delay 500/s      d    0.049%    0.051%    100%    0.92      20.3
//! dynid filt.+delay 500/s      r    0.062%    0.064%     92%    0.97      20.3
//! dynid filt.+delay 500/s     f0    0.285%    0.307%    100%    0.96      20.3
//! IDIM-LS, OLS errors         m    0.025%    0.025%    100%    1.00       1.4
//! IDIM-LS, OLS errors         d    0.076%    0.147%    100%    0.52       1.4
//! IDIM-LS, OLS errors         r    0.368%    0.199%     67%    1.84       1.4
//! IDIM-LS, OLS errors        f0    0.234%    0.914%    100%    0.26       1.4
//! IDIM-LS, HAC errors         m    0.025%    0.015%     83%    1.64       1.4
//! IDIM-LS, HAC errors         d    0.076%    0.099%    100%    0.77       1.4
//! IDIM-LS, HAC errors         r    0.368%    0.157%     17%    2.35       1.4
//! IDIM-LS, HAC errors        f0    0.234%    0.524%    100%    0.45       1.4
//! SVF-LS 10 Hz, HAC           m    0.282%    0.098%      0%    2.89     142.9
//! SVF-LS 10 Hz, HAC           d   15.825%    2.439%      0%    6.49     142.9
//! SVF-LS 10 Hz, HAC           r   26.551%    2.925%      0%    9.08     142.9
//! SVF-LS 10 Hz, HAC          f0    2.726%   27.672%    100%    0.10     142.9
//! SVF-LS 80 Hz, HAC           m    0.014%    0.225%    100%    0.06      21.2
//! SVF-LS 80 Hz, HAC           d   27.561%    2.601%      0%   10.59      21.2
//! SVF-LS 80 Hz, HAC           r   47.352%    3.753%      0%   12.62      21.2
//! SVF-LS 80 Hz, HAC          f0    9.814%   17.156%    100%    0.57      21.2
//! SVF-LS 80 Hz, EIV comp.      m    0.035%    0.225%    100%    0.16      20.7
//! SVF-LS 80 Hz, EIV comp.      d   27.561%    2.601%      0%   10.59      20.7
//! SVF-LS 80 Hz, EIV comp.      r   47.352%    3.753%      0%   12.62      20.7
//! SVF-LS 80 Hz, EIV comp.     f0    9.814%   17.155%    100%    0.57      20.7
//! SVF-LS 80 Hz, rests out      m    0.007%    0.011%    100%    0.62      14.7
//! SVF-LS 80 Hz, rests out      d    0.212%    0.056%      0%    3.81      14.7
//! SVF-LS 80 Hz, rests out      r    0.110%    0.078%     83%    1.41      14.7
//! SVF-LS 80 Hz, rests out     f0    0.288%    0.341%    100%    0.84      14.7
//! SVF-LS 80, rests+EIV        m    0.013%    0.011%    100%    1.21      14.6
//! SVF-LS 80, rests+EIV        d    0.214%    0.056%      0%    3.82      14.6
//! SVF-LS 80, rests+EIV        r    0.114%    0.077%     83%    1.47      14.6
//! SVF-LS 80, rests+EIV       f0    0.288%    0.341%    100%    0.84      14.6
//!
//! planned moves, Stribeck friction not in the model
//! method                  param   RMS err   mean SE   cover    e/SE    ms/rec
//! dynid (defaults)            m    2.044%    0.150%      0%   13.60      30.9
//! dynid (defaults)            d    4.446%    1.273%      0%    3.49      30.9
//! dynid (defaults)            r    5.283%    2.470%      0%    2.14      30.9
//! dynid (defaults)           f0    0.232%    3.047%    100%    0.08      30.9
//! dynid --column-chains       m    1.979%    0.193%      0%   10.27      32.6
//! dynid --column-chains       d    4.090%    1.185%      0%    3.45      32.6
//! dynid --column-chains       r    4.971%    2.008%      0%    2.47      32.6
//! dynid --column-chains      f0    0.243%    2.826%    100%    0.09      32.6
//! dynid chains, 2-step        m    2.147%    0.138%      0%   15.58      32.8
//! dynid chains, 2-step        d    6.534%    1.391%      0%    4.70      32.8
//! dynid chains, 2-step        r    8.070%    0.966%      0%    8.40      32.8
//! dynid chains, 2-step       f0    3.251%    3.758%    100%    0.87      32.8
//! dynid to noise floor        m    1.092%    0.117%      0%    9.34      30.2
//! dynid to noise floor        d    2.268%    0.613%      0%    3.72      30.2
//! dynid to noise floor        r    3.093%    1.346%      0%    2.30      30.2
//! dynid to noise floor       f0    0.748%    1.966%    100%    0.38      30.2
//! dynid chains 2-step nf      m    2.064%    0.126%      0%   16.44      31.6
//! dynid chains 2-step nf      d    3.948%    0.781%      0%    5.05      31.6
//! dynid chains 2-step nf      r    4.467%    1.101%      0%    4.06      31.6
//! dynid chains 2-step nf     f0    2.567%    2.224%    100%    1.16      31.6
//! dynid --keep-rests          m   33.784%    3.272%      0%   10.33      29.5
//! dynid --keep-rests          d   96.495%    8.970%      0%   10.76      29.5
//! dynid --keep-rests          r  100.948%   14.321%      0%    7.05      29.5
//! dynid --keep-rests         f0    3.311%   12.592%    100%    0.26      29.5
//! dynid --filtered-eq.        m    0.040%    0.017%     33%    2.37      29.6
//! dynid --filtered-eq.        d    1.392%    0.179%      0%    7.80      29.6
//! dynid --filtered-eq.        r    2.227%    0.352%      0%    6.33      29.6
//! dynid --filtered-eq.       f0    0.313%    1.517%    100%    0.21      29.6
//! dynid filtered 20 Hz        m    0.067%    0.023%      8%    2.95      29.7
//! dynid filtered 20 Hz        d    0.561%    0.083%      0%    6.86      29.7
//! dynid filtered 20 Hz        r    0.880%    0.190%      0%    4.68      29.7
//! dynid filtered 20 Hz       f0    0.389%    0.779%    100%    0.50      29.7
//! dynid filtered 160 Hz       m    0.188%    0.018%      0%   10.74      29.9
//! dynid filtered 160 Hz       d    2.558%    0.355%      0%    7.22      29.9
//! dynid filtered 160 Hz       r    4.211%    0.608%      0%    6.92      29.9
//! dynid filtered 160 Hz      f0    0.258%    2.881%    100%    0.09      29.9
//! dynid --input-delay         m    1.600%    0.098%      0%   16.41      30.3
//! dynid --input-delay         d    2.243%    1.500%    100%    1.49      30.3
//! dynid --input-delay         r    3.446%    2.076%    100%    1.66      30.3
//! dynid --input-delay        f0    0.533%    1.883%    100%    0.28      30.3
//! dynid filtered + delay      m    0.042%    0.018%     33%    2.43      30.5
//! dynid filtered + delay      d    1.023%    0.169%      0%    6.08      30.5
//! dynid filtered + delay      r    1.666%    0.325%      0%    5.14      30.5
//! dynid filtered + delay     f0    0.317%    1.216%    100%    0.26      30.5
//! dynid filt.+delay 500/s      m    0.008%    0.014%    100%    0.58      27.7
//! dynid filt.+delay 500/s      d    2.064%    0.325%      0%    6.35      27.7
//! dynid filt.+delay 500/s      r    3.500%    0.553%      0%    6.33      27.7
//! dynid filt.+delay 500/s     f0    0.273%    2.454%    100%    0.11      27.7
//! IDIM-LS, OLS errors         m    0.047%    0.032%    100%    1.44       1.5
//! IDIM-LS, OLS errors         d    3.369%    0.191%      0%   17.65       1.5
//! IDIM-LS, OLS errors         r    5.596%    0.259%      0%   21.59       1.5
//! IDIM-LS, OLS errors        f0    0.241%    1.181%    100%    0.20       1.5
//! IDIM-LS, HAC errors         m    0.047%    0.027%     92%    1.73       1.5
//! IDIM-LS, HAC errors         d    3.369%    0.405%      0%    8.32       1.5
//! IDIM-LS, HAC errors         r    5.596%    0.627%      0%    8.93       1.5
//! IDIM-LS, HAC errors        f0    0.241%    2.024%    100%    0.12       1.5
//! SVF-LS 10 Hz, HAC           m    0.315%    0.092%      0%    3.44     150.0
//! SVF-LS 10 Hz, HAC           d   13.450%    2.384%      0%    5.64     150.0
//! SVF-LS 10 Hz, HAC           r   22.585%    3.043%      0%    7.42     150.0
//! SVF-LS 10 Hz, HAC          f0    4.661%   37.101%    100%    0.13     150.0
//! SVF-LS 80 Hz, HAC           m    0.032%    0.176%    100%    0.18      22.5
//! SVF-LS 80 Hz, HAC           d   20.549%    2.280%      0%    9.01      22.5
//! SVF-LS 80 Hz, HAC           r   35.287%    3.465%      0%   10.18      22.5
//! SVF-LS 80 Hz, HAC          f0   19.365%   18.474%    100%    1.05      22.5
//! SVF-LS 80 Hz, EIV comp.      m    0.053%    0.176%    100%    0.30      21.7
//! SVF-LS 80 Hz, EIV comp.      d   20.549%    2.280%      0%    9.01      21.7
//! SVF-LS 80 Hz, EIV comp.      r   35.287%    3.465%      0%   10.18      21.7
//! SVF-LS 80 Hz, EIV comp.     f0   19.365%   18.473%    100%    1.05      21.7
//! SVF-LS 80 Hz, rests out      m    0.027%    0.021%    100%    1.28      16.0
//! SVF-LS 80 Hz, rests out      d    2.495%    0.341%      0%    7.32      16.0
//! SVF-LS 80 Hz, rests out      r    4.083%    0.533%      0%    7.66      16.0
//! SVF-LS 80 Hz, rests out     f0    0.257%    1.508%    100%    0.17      16.0
//! SVF-LS 80, rests+EIV        m    0.012%    0.021%    100%    0.59      15.8
//! SVF-LS 80, rests+EIV        d    2.498%    0.341%      0%    7.34      15.8
//! SVF-LS 80, rests+EIV        r    4.088%    0.533%      0%    7.67      15.8
//! SVF-LS 80, rests+EIV       f0    0.257%    1.504%    100%    0.17      15.8
//! ```
//!
//! **Rows of the filtered equation** (`--filtered-eq.`: `IdentifyOptions::filtered`, one
//! corner designed as the encoder's information bandwidth capped at 0.5/Ts = 500 rad/s;
//! `filtered 20 Hz`, `160 Hz`: the corner given as 126 and 1005 rad/s; docs/method.md §2).
//! On random references m 0.009 %, d 0.152 %, r 0.091 %, f0 0.091 % — against the defaults
//! 1.6×, 3.1×, 15× and 16× smaller, level with SVF-LS 80 Hz with its rows near rest dropped
//! (0.007, 0.149, 0.076, 0.097 %), f0 below every baseline; on planned moves m 0.009 % and
//! r 0.105 % (below IDIM-LS's 0.025 and 0.368 %, level with SVF-LS rests out), but d 0.207 %
//! (IDIM-LS 0.076 %) and f0 0.305 % (0.234 %); with the Stribeck term the model lacks it
//! moves least of all methods (m 0.040, d 1.4, r 2.2 %). Its damping errors are a bias the
//! standard errors do not cover (coverage 0 % on both suites), the same bias as SVF-LS
//! rests out's: the force's path between samples. With `DYNID_BENCH_INPUT_OVERSAMPLE=100`
//! (seeds 1–6) it falls to d 0.015 % random / 0.031 % planned (IDIM-LS 0.29 / 0.28 %),
//! m 0.005 / 0.010 %, r 0.011 / 0.054 %, f0 0.090 / 0.248 %, with coverage 6 of 6 on the
//! planned moves; with `=1` both filtered regressions give d 1.4 %. The 160 Hz corner
//! (λTs = 1) biases the mass by 0.13 %, the 20 Hz corner the friction on random references
//! (0.19 %): hence the
//! cap at 0.5/Ts.
//!
//! **Input delay** (`dynid --input-delay`, `filtered + delay`: `IdentifyOptions::input_delay`,
//! one unknown delay of the force, docs/method.md §2, "The input between samples"; the
//! filtered rows' corner designed at most 0.25/Ts = 250 rad/s with it, `500/s`: given at the
//! cap without it). With the filtered rows it removes their damping bias: random m 0.005,
//! d 0.005, r 0.010, f0 0.069 % — below the best baseline on every parameter (SVF-LS rests
//! out 0.007, 0.149, 0.076, 0.097 %; SVF-LS 80 Hz d 0.096 %), every one covered on 83–100 %
//! of the seeds (at 500 rad/s the mass's coverage is 42 %, RMS e/SE 2.24); planned m 0.008,
//! d 0.050, r 0.060, f0 0.319 % with coverage 92–100 % — d and r below every baseline, m just
//! above SVF-LS rests out's 0.007 %, f0 above IDIM-LS's 0.234 %. It does not cure a model
//! error: with the Stribeck term the filtered rows' d and r stay 1.0 and 1.7 % off, and with
//! the default instrument rows the delay takes part of the model error up and moves the mass
//! by 1.6 % (16 standard errors). On the default rows alone it changes little (random d
//! 0.47 → 0.50 %).
//!
//! **SVF-LS variants** (`SvfOptions`, 80 Hz): `EIV comp.` takes the encoder's rounding
//! (white, 1 µm²/12) out of the normal matrix; `rests out` drops every row whose filter
//! memory holds a sample with the aligned filtered velocity below 1 mm/s; `rests+EIV` both.
//! The compensation does not remove the mass error on random references (0.027 → 0.034 %,
//! e/SE 4.45 → 5.58): that error is the estimator's own — it is there without noise or
//! quantisation (+0.03 %, `baseline::tests::noise_free_servo_axis_is_recovered`) — and not
//! errors in the variables (which the compensation does remove where they are, test
//! `baseline::tests::compensation_removes_the_noise_bias_and_rests_drop_rows`). Dropping
//! the rows near rest is what helps: on random references (where it drops the rows near the
//! velocity's zero crossings) m 0.007 %, r 0.076 %, f0 0.097 % — the smallest errors of any
//! method here — but d 0.149 % with a standard error 6× too small (coverage 0 %); on
//! planned moves it removes SVF-LS's failure at the rests (d 27.6 → 0.21 %, r 47 → 0.11 %,
//! m 0.007 %, f0 0.29 %), d again with errors 3.8× too small; with the Stribeck term d and
//! r move by 2.5 and 4.1 % (IDIM-LS 3.4, 5.6 %; dynid 4.4, 5.3 %). So an estimator at the
//! precision of the filtered-equation regression needs, besides its rows, standard errors
//! that cover the damping (the Newey–West lag of twice the filter memory does not).
//!
//! **Random reference.** dynid's errors are honest and its mass error the smallest;
//! IDIM-LS's RMS errors of d, r and f0 are 2.9×, 1.7× and 2.3× smaller, SVF-LS's at 80 Hz
//! 5×, 9× and 4.7×, but both baselines carry biases their standard errors do not cover
//! (IDIM-LS r −0.6 to −1.1 %, its classical and HAC coverage of r 0 %; measured without
//! quantisation in `baseline::tests::noise_free_servo_axis_is_recovered`).
//! `--column-chains` cuts dynid's d, r and f0 errors by 40–50 % and raises its mass error
//! (docs/method.md §2). The two-step weighting on top of the chains (`chains, 2-step`:
//! `IdentifyOptions { column_chains, efficient }`, opt-in, docs/method.md §5) brings the
//! mass back to 0.013 % and cuts d and r by a further 22 %, but the offset's error grows
//! (0.86 → 1.18 %) and every standard error comes out 2–3.7 times too small (coverage
//! 50–83 %): not honest, hence not the default. Rests are left out only where they hold 5 % of a level's samples
//! or more: no random record reaches that, so the defaults and `--keep-rests` give the
//! same estimates there; the defaults' `ms/rec` includes the two passes that look for
//! rests (8.5 against 5.6 ms per record in this run).
//!
//! **Corners to the noise floor** (`to noise floor`: the highest corner raised to where the
//! encoder stands above its noise floor, capped at a fifth of the Nyquist frequency, about
//! 628 rad/s; `chains 2-step nf`: the same with column chains and the two-step weighting).
//! On random set points the raised corner makes every error larger (d 0.47 → 1.86 %, r
//! 1.36 → 5.03 %), with honest errors; with chains and two steps the errors come out nearly
//! honest (coverage 83–100 %, e/SE 1.06–1.46; m 0.012, d 0.194, r 0.599, f0 0.890 %), still
//! above SVF-LS 80 Hz's d and r. On planned moves the raised corner makes m, d and r worse
//! than the defaults (0.053, 0.36, 0.40 % against 0.027, 0.13, 0.21 %) with errors that do
//! not cover them; with the Stribeck term the model lacks it moves every estimate less than
//! the defaults (m 1.1, d 2.3, r 3.1 % against 2.0, 4.4, 5.3 %; IDIM-LS d 3.4, r 5.6 %). No one corner rule wins on all
//! three suites: the defaults stay.
//!
//! **Planned moves** (a third of every cycle at rest). dynid leaves the rests out of its
//! moments (docs/method.md §7): RMS errors m 0.027 %, d 0.129 %, r 0.210 %, f0 0.239 %,
//! with honest errors for all four (coverage 92–100 %, e/SE 0.75–0.93) — below IDIM-LS's
//! for r (0.368 %), level with it for m (0.025 %) and f0 (0.234 %), 1.7× IDIM-LS's for d
//! (0.076 %). Before the velocity estimate fitted the reversals (the overshoots at the
//! ends of moves, where the Coulomb force flips and the smoothing differentiator crossed
//! zero a quarter of a sample late; `runtime/src/ident/velocity.rs`, docs/method.md §7), the
//! mass carried a bias of +0.09 % (RMS 0.094 %, coverage 0 %). SVF-LS at 80 Hz with its rows
//! near rest dropped (`rests out`) is the better baseline here for m (0.007 %) and r (0.110
//! %), its damping errors 4× too small (coverage 0 %). The two-step
//! //! weighting gives m 0.070 % (coverage 42 %). With the rests kept
//! (`--keep-rests`) the mass is off by 23 %, damping and friction by 67 %: at rest the
//! Coulomb force lies anywhere in ±fc while the model says `r·sign(v̂)`. SVF-LS, which
//! keeps the rows at rest, fails the same way (d 16–28 %, r 27–47 %). With a Stribeck term
//! the model lacks, dynid's friction split moves by 4.4–5.3 % (IDIM-LS 3.4–5.6 %), its
//! mass by 2.0 % (IDIM-LS 0.05 %), all at several of their standard errors; the two-step
//! weighting moves the friction split further (d 6.5 %, r 8.1 %).
//!
//! IDIM-LS's Newey–West errors come out below its classical ones (the decimated residuals
//! are negatively correlated at short lags). `ms/rec` is the wall time per record with the
//! seeds run in parallel (SVF-LS at 10 Hz spends it on the Newey–West sum over 382 lags).

use dynid_ir::ir::ModelIr;
use dynid_runtime::baseline::{self, Fit, IdimOptions, SvfOptions};
use dynid_runtime::data::{LevelSource, RecordSource};
use dynid_runtime::ident::IdentifyOptions;
use dynid_runtime::record::Record;
use dynid_runtime::sim::{self, test_models::ServoAxis};
use rayon::prelude::*;
use std::time::Instant;

mod common;

/// Truth of the axis: dynid's parameter names and values, in the order of
/// [`baseline::SERVO_TERMS`].
const TRUTH: [(&str, f64); 4] = [("m", 50.0), ("d", 120.0), ("r", 15.0), ("f0", -2.0)];

/// How the axis is moved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Trajectory {
    /// The smooth random reference of `tests/servo.rs` (10 cm RMS, corner 5 rad/s).
    Random,
    /// Planned point-to-point moves ([`ServoAxis::planned`]: 10 cm out and back at 0.4,
    /// 0.2 and 0.1 m/s, 0.33 s at rest before each move, four identical cycles).
    Planned,
    /// The planned moves on an axis whose friction has a Stribeck term that the model
    /// lacks: 5 N more at rest, falling off over 10 mm/s.
    PlannedStribeck,
}

impl Trajectory {
    const ALL: [Trajectory; 3] = [
        Trajectory::Random,
        Trajectory::Planned,
        Trajectory::PlannedStribeck,
    ];

    fn label(self) -> &'static str {
        match self {
            Trajectory::Random => "random reference",
            Trajectory::Planned => "planned moves",
            Trajectory::PlannedStribeck => "planned moves, Stribeck friction not in the model",
        }
    }
}

/// The identification model and one record of the servo axis moved by `kind` at `seed`
/// (simulated with the axis's true model, which may hold forces the model lacks).
fn record(kind: Trajectory, seed: u64) -> (ModelIr, Record) {
    let mut axis = match kind {
        Trajectory::Random => {
            let mut a = ServoAxis::standard();
            a.reference.rms = 0.1;
            a
        }
        Trajectory::Planned | Trajectory::PlannedStribeck => ServoAxis::planned(),
    };
    axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
    if kind == Trajectory::PlannedStribeck {
        axis.model_error = vec![ServoAxis::stribeck(5.0, 0.01)];
    }
    let mut cfg = axis.config(seed);
    cfg.input_oversample = oversample();
    let mut out =
        sim::simulate(&axis.true_model(), &cfg).expect("invariant: the servo axis simulates");
    let mut rec = out.records.remove(0);
    if kind != Trajectory::Random {
        // A planned record has nothing random in it (the encoder's rounding is
        // deterministic): the seed draws white noise on the force, 1 % of its spread, as a
        // drive's current measurement carries.
        sim::test_models::add_noise(&mut rec, "u", 0.01, seed);
    }
    (axis.model(), rec)
}

/// Controller updates per sample interval: 10, or `DYNID_BENCH_INPUT_OVERSAMPLE` (the
/// force's path between samples is what biases the damping at 10, see the module doc).
fn oversample() -> usize {
    std::env::var("DYNID_BENCH_INPUT_OVERSAMPLE")
        .ok()
        .map(|s| {
            s.parse()
                .expect("DYNID_BENCH_INPUT_OVERSAMPLE is a whole number")
        })
        .unwrap_or(10)
}

/// One estimate: `(value, standard error)` per parameter of [`TRUTH`], `None` where the
/// method gave none.
type Estimate = Vec<Option<(f64, f64)>>;

/// The methods compared, by name.
const METHODS: [&str; 19] = [
    "dynid (defaults)",
    "dynid --column-chains",
    "dynid chains, 2-step",
    "dynid to noise floor",
    "dynid chains 2-step nf",
    "dynid --keep-rests",
    "dynid --filtered-eq.",
    "dynid filtered 20 Hz",
    "dynid filtered 160 Hz",
    "dynid --input-delay",
    "dynid filtered + delay",
    "dynid filt.+delay 500/s",
    "IDIM-LS, OLS errors",
    "IDIM-LS, HAC errors",
    "SVF-LS 10 Hz, HAC",
    "SVF-LS 80 Hz, HAC",
    "SVF-LS 80 Hz, EIV comp.",
    "SVF-LS 80 Hz, rests out",
    "SVF-LS 80, rests+EIV",
];

/// Every method of [`METHODS`] on one record, each with its wall time in seconds.
fn run_all(ir: &ModelIr, rec: &Record, selected: &[bool]) -> Vec<(Estimate, f64)> {
    let timed = |f: &dyn Fn() -> Estimate| {
        let t = Instant::now();
        let e = f();
        (e, t.elapsed().as_secs_f64())
    };
    let from_fit = |fit: &Result<Fit, baseline::BaselineError>, hac: bool| -> Estimate {
        match fit {
            Ok(fit) => (0..TRUTH.len())
                .map(|j| {
                    let se = if hac {
                        fit.stderr_hac[j]
                    } else {
                        fit.stderr_ols[j]
                    };
                    Some((fit.estimates[j], se))
                })
                .collect(),
            Err(e) => {
                eprintln!("baseline failed: {e}");
                vec![None; TRUTH.len()]
            }
        }
    };
    let dynid = |opts: IdentifyOptions| {
        timed(&|| {
            let src = RecordSource::new(rec, ir, "servo").expect("invariant: a simulated record");
            let levels: Vec<&dyn LevelSource> = vec![&src];
            match dynid_runtime::identify(ir, &levels, &opts) {
                Ok(id) => TRUTH
                    .iter()
                    .map(|(n, _)| id.param(n).map(|p| (p.value, p.stderr)))
                    .collect(),
                Err(e) => {
                    eprintln!("identify failed: {e}");
                    vec![None; TRUTH.len()]
                }
            }
        })
    };
    // The highest corner raised to the band where the encoder stands above its noise floor
    // (`FilterSummary::corners_from`, capped at a fifth of the Nyquist frequency), the
    // lowest kept, six corners log-spaced between.
    let to_floor = |opts: IdentifyOptions| {
        let src = RecordSource::new(rec, ir, "servo").expect("invariant: a simulated record");
        let levels: Vec<&dyn LevelSource> = vec![&src];
        let corners: Option<Vec<f64>> =
            dynid_runtime::identify(ir, &levels, &IdentifyOptions::default())
                .ok()
                .and_then(|id| {
                    let lo = id
                        .filter
                        .corners
                        .iter()
                        .copied()
                        .fold(f64::INFINITY, f64::min);
                    let ts = id.levels[0].ts;
                    let top = id
                        .filter
                        .corners_from
                        .info_bandwidth?
                        .min(std::f64::consts::PI / ts / 5.0);
                    Some(
                        (0..6)
                            .map(|i| lo * (top / lo).powf(i as f64 / 5.0))
                            .collect(),
                    )
                });
        dynid(IdentifyOptions { corners, ..opts })
    };
    // IDIM-LS once per record (two rows read it), timed, and only if a row is selected.
    let idim_run = std::cell::OnceCell::new();
    let idim = |hac: bool| {
        let (fit, seconds) = idim_run.get_or_init(|| {
            let t = Instant::now();
            let fit = baseline::idim_ls(rec, "m.x", "u", &IdimOptions::default());
            (fit, t.elapsed().as_secs_f64())
        });
        (from_fit(fit, hac), *seconds)
    };
    let svf_with =
        |opts: SvfOptions| timed(&|| from_fit(&baseline::svf_ls(rec, "m.x", "u", &opts), true));
    let svf = |hz: f64| svf_with(SvfOptions::at(hz));
    // The encoder's rounding to 1 µm: white, variance q²/12.
    let eiv = |rest: f64| SvfOptions {
        position_noise_var: 1e-12 / 12.0,
        rest,
        ..SvfOptions::at(80.0)
    };
    let filtered = |hz: f64| IdentifyOptions {
        filtered: true,
        corners: Some(vec![2.0 * std::f64::consts::PI * hz]),
        ..Default::default()
    };
    type Method<'a> = Box<dyn Fn() -> (Estimate, f64) + 'a>;
    let methods: Vec<Method> = vec![
        Box::new(|| dynid(IdentifyOptions::default())),
        Box::new(|| {
            dynid(IdentifyOptions {
                column_chains: true,
                ..Default::default()
            })
        }),
        Box::new(|| {
            dynid(IdentifyOptions {
                column_chains: true,
                efficient: true,
                ..Default::default()
            })
        }),
        Box::new(|| to_floor(IdentifyOptions::default())),
        Box::new(|| {
            to_floor(IdentifyOptions {
                column_chains: true,
                efficient: true,
                ..Default::default()
            })
        }),
        Box::new(|| {
            dynid(IdentifyOptions {
                keep_rests: true,
                ..Default::default()
            })
        }),
        Box::new(|| {
            dynid(IdentifyOptions {
                filtered: true,
                ..Default::default()
            })
        }),
        Box::new(|| dynid(filtered(20.0))),
        Box::new(|| dynid(filtered(160.0))),
        Box::new(|| {
            dynid(IdentifyOptions {
                input_delay: true,
                ..Default::default()
            })
        }),
        Box::new(|| {
            dynid(IdentifyOptions {
                filtered: true,
                input_delay: true,
                ..Default::default()
            })
        }),
        Box::new(|| {
            // The cap of the filtered rows without the delay, 0.5/Ts.
            dynid(IdentifyOptions {
                filtered: true,
                input_delay: true,
                corners: Some(vec![500.0]),
                ..Default::default()
            })
        }),
        Box::new(|| idim(false)),
        Box::new(|| idim(true)),
        Box::new(|| svf(10.0)),
        Box::new(|| svf(80.0)),
        Box::new(|| svf_with(eiv(0.0))),
        Box::new(|| {
            svf_with(SvfOptions {
                rest: 1e-3,
                ..SvfOptions::at(80.0)
            })
        }),
        Box::new(|| svf_with(eiv(1e-3))),
    ];
    methods
        .iter()
        .zip(selected)
        .map(|(m, &on)| {
            if on {
                m()
            } else {
                (vec![None; TRUTH.len()], 0.0)
            }
        })
        .collect()
}

/// Figures of one method and parameter over the seeds.
#[derive(serde::Serialize)]
struct Row {
    trajectory: &'static str,
    method: &'static str,
    param: &'static str,
    /// Seeds with an estimate.
    n: usize,
    /// RMS of (estimate / truth − 1).
    rms_error: f64,
    /// Mean of SE / |truth|.
    mean_se: f64,
    /// Fraction of seeds with |error| < 2 SE.
    coverage: f64,
    /// RMS of error / SE.
    rms_z: f64,
    /// Mean wall time of the method per record, seconds.
    seconds: f64,
}

fn main() {
    let json = std::env::args().any(|a| a == "--json");
    let seeds: u64 = std::env::var("DYNID_BENCH_SEEDS")
        .ok()
        .map(|s| s.parse().expect("DYNID_BENCH_SEEDS is a whole number"))
        .unwrap_or(12);
    // `DYNID_BENCH_METHODS=filtered,SVF-LS 80`: only the methods whose name holds one of
    // the comma-separated parts.
    let only = std::env::var("DYNID_BENCH_METHODS").ok();
    let selected: Vec<bool> = METHODS
        .iter()
        .map(|m| {
            only.as_ref()
                .is_none_or(|o| o.split(',').any(|p| m.contains(p)))
        })
        .collect();
    let mut rows = Vec::new();
    for kind in Trajectory::ALL {
        // Seeds in parallel; each result keeps its seed's place.
        let runs: Vec<Vec<(Estimate, f64)>> = (1..=seeds)
            .into_par_iter()
            .map(|seed| {
                let (ir, rec) = record(kind, seed);
                run_all(&ir, &rec, &selected)
            })
            .collect();
        for (m, method) in METHODS.iter().enumerate().filter(|(m, _)| selected[*m]) {
            let seconds = runs.iter().map(|r| r[m].1).sum::<f64>() / runs.len() as f64;
            for (j, (param, truth)) in TRUTH.iter().enumerate() {
                let pairs: Vec<(f64, f64)> = runs
                    .iter()
                    .filter_map(|r| r[m].0[j])
                    .map(|(v, se)| ((v - truth) / truth.abs(), se / truth.abs()))
                    .collect();
                let n = pairs.len().max(1) as f64;
                let ms = |f: &dyn Fn(&(f64, f64)) -> f64| {
                    (pairs.iter().map(|p| f(p).powi(2)).sum::<f64>() / n).sqrt()
                };
                rows.push(Row {
                    trajectory: kind.label(),
                    method,
                    param,
                    n: pairs.len(),
                    rms_error: ms(&|p| p.0),
                    mean_se: pairs.iter().map(|p| p.1).sum::<f64>() / n,
                    coverage: pairs.iter().filter(|p| p.0.abs() < 2.0 * p.1).count() as f64 / n,
                    rms_z: ms(&|p| if p.1 > 0.0 { p.0 / p.1 } else { 0.0 }),
                    seconds,
                });
            }
        }
    }
    if json {
        println!(
            "{}",
            serde_json::to_string(&serde_json::json!({ "seeds": seeds, "rows": rows }))
                .expect("invariant: plain numbers and strings serialise")
        );
        return;
    }
    println!("servo axis, seeds 1–{seeds}: RMS error, mean SE (both % of the truth), coverage |e| < 2 SE, RMS e/SE");
    for kind in Trajectory::ALL {
        println!("\n{}", kind.label());
        println!(
            "{:<22} {:>6} {:>9} {:>9} {:>7} {:>7} {:>9}",
            "method", "param", "RMS err", "mean SE", "cover", "e/SE", "ms/rec"
        );
        for r in rows.iter().filter(|r| r.trajectory == kind.label()) {
            println!(
                "{:<22} {:>6} {:>8.3}% {:>8.3}% {:>6.0}% {:>7.2} {:>9.1}",
                r.method,
                r.param,
                100.0 * r.rms_error,
                100.0 * r.mean_se,
                100.0 * r.coverage,
                r.rms_z,
                1e3 * r.seconds
            );
        }
    }
    // The row of docs/performance.md: dynid's defaults against IDIM-LS (HAC errors) on d.
    let find = |kind: Trajectory, method: &str| {
        rows.iter()
            .find(|r| r.trajectory == kind.label() && r.method == method && r.param == "d")
    };
    let figure = Trajectory::ALL
        .iter()
        .filter_map(|&kind| {
            let (ours, idim) = (find(kind, METHODS[0])?, find(kind, "IDIM-LS, HAC errors")?);
            Some(format!(
                "{}, d: RMS error {:.1}× IDIM-LS's, RMS error / SE {:.2} (IDIM-LS {:.2})",
                kind.label(),
                ours.rms_error / idim.rms_error,
                ours.rms_z,
                idim.rms_z
            ))
        })
        .collect::<Vec<_>>()
        .join("; ");
    common::print_row(
        "servo_precision",
        &figure,
        "IDIM-LS and SVF-LS (`baseline`) on the same records",
        &format!(
            "{}cargo bench -p dynid-runtime --bench servo_precision",
            common::bench_env()
        ),
    );
}
