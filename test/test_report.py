# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of report: PNG plots, text / markdown tables and the markdown report writer."""
import subprocess
import sys

from matplotlib.colors import to_rgb
from matplotlib.image import imread
import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.report import tables
from wheel_force_estimator.report.builders import paired_inputs
from wheel_force_estimator.report.evaluation_plots import _envelope
from wheel_force_estimator.report.evaluation_plots import _MAX_LINE_POINTS
from wheel_force_estimator.report.evaluation_plots import plot_damage_ratio
from wheel_force_estimator.report.evaluation_plots import plot_relative_damage_spectrum
from wheel_force_estimator.report.evaluation_plots import plot_rmse_colormap
from wheel_force_estimator.report.evaluation_plots import plot_time_overlay
from wheel_force_estimator.report.figures import RUBRIC_COLORS
from wheel_force_estimator.report.markdown import ReportWriter
from wheel_force_estimator.report.spectral_plots import plot_asd
from wheel_force_estimator.report.spectral_plots import plot_coherence
from wheel_force_estimator.report.spectral_plots import plot_condition_number
from wheel_force_estimator.report.spectral_plots import plot_frf_diagonal
from wheel_force_estimator.report.spectral_plots import plot_frf_matrix

PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'
FS_HZ = 128.0
PAPER_BANDS = [(0.0, 2.2), (1.8, 4.4), (3.6, 8.8), (7.2, 17.6), (14.4, 32.0)]


def _rgb(path):
    """Return the (h, w, 3) float RGB image after checking the PNG signature."""
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    return imread(path)[:, :, :3]


def _assert_png(path, size_px=None):
    """Check a real, non-blank PNG: several colours and a non-trivial share of ink."""
    img = _rgb(path)
    if size_px is not None:
        assert img.shape[:2] == size_px
    # Pack 8-bit RGB into one integer: np.unique on rows of floats is slow on 5 Mpixel images.
    rgb8 = np.round(img[::2, ::2] * 255).astype(np.uint32)
    colours = np.unique((rgb8[..., 0] << 16) | (rgb8[..., 1] << 8) | rgb8[..., 2])
    assert colours.size > 10, 'image is (nearly) a single colour'
    ink = np.mean(np.any(img < 0.9, axis=2))
    assert ink > 0.01, f'only {ink:.3%} of the image is drawn on'


@pytest.fixture
def rng():
    return np.random.default_rng(20260101)


@pytest.fixture
def f_hz():
    return np.linspace(0.0, FS_HZ / 2, 65)


# ---------------------------------------------------------------- plots: real PNGs
def test_plot_coherence_writes_png_of_documented_size(tmp_path, rng, f_hz):
    multiple = rng.uniform(0.3, 1.0, (f_hz.size, 12))
    ordinary = multiple * rng.uniform(0.5, 1.0, multiple.shape)
    out = plot_coherence(tmp_path / 'coherence.png', f_hz, multiple, ordinary,
                         OUTPUT_CHANNELS, f_max_hz=40.0)
    assert out == tmp_path / 'coherence.png'
    # 4 corner rows x 3 axis columns of 4.2 x 2.3 in cells + margins, 150 dpi: 13.2 x 10.2 in.
    _assert_png(out, size_px=(1530, 1980))


def test_plot_coherence_without_ordinary(tmp_path, rng, f_hz):
    out = plot_coherence(tmp_path / 'c.png', f_hz, rng.uniform(0, 1, (f_hz.size, 12)),
                         None, OUTPUT_CHANNELS)
    _assert_png(out)


def test_plot_frf_diagonal(tmp_path, rng, f_hz):
    s = 2j * np.pi * f_hz
    wn = 2 * np.pi * 10.0
    h = 0.05 * (rng.standard_normal((f_hz.size, 12, 12))
                + 1j * rng.standard_normal((f_hz.size, 12, 12)))
    for k in range(12):
        h[:, k, k] += 400.0 * wn**2 / (s**2 + 0.4 * wn * s + wn**2)
    _assert_png(plot_frf_diagonal(tmp_path / 'frf.png', f_hz, h, INPUT_CHANNELS,
                                  OUTPUT_CHANNELS, f_max_hz=50.0))


def test_plot_frf_diagonal_without_same_axis_pair(tmp_path, f_hz):
    h = np.ones((f_hz.size, 1, 1), complex)
    with pytest.raises(ConfigError, match='same-axis'):
        plot_frf_diagonal(tmp_path / 'frf.png', f_hz, h, ['lf_ax'], ['rf_fx'])


def test_plot_time_overlay_full_and_zoom(tmp_path, rng):
    t_s = np.arange(4096) / FS_HZ
    target = rng.standard_normal((12, t_s.size)) * 1000.0
    prediction = target + rng.standard_normal(target.shape) * 100.0
    full = plot_time_overlay(tmp_path / 'full.png', t_s, target, prediction,
                             OUTPUT_CHANNELS, title='run1')
    zoom = plot_time_overlay(tmp_path / 'zoom.png', t_s, target, prediction,
                             OUTPUT_CHANNELS, window_s=(10.0, 12.0), title='run1')
    _assert_png(full)
    _assert_png(zoom)
    assert not np.array_equal(_rgb(full), _rgb(zoom))


def test_plot_time_overlay_long_record_keeps_peaks():
    # The display envelope must keep every extreme: a one-sample spike anywhere survives.
    t_s = np.arange(100_003) / FS_HZ
    for index in (0, 1, 54_321, t_s.size - 1):
        for sign in (1.0, -1.0):
            y = np.zeros(t_s.size)
            y[index] = sign * 7.0
            t_env, y_env = _envelope(t_s, y)
            assert y_env.size <= _MAX_LINE_POINTS
            assert (y_env.max(), y_env.min()) == (max(sign * 7.0, 0.0), min(sign * 7.0, 0.0))
            assert np.all(np.diff(t_env) >= 0.0)


def test_plot_asd_with_and_without_frf(tmp_path, rng, f_hz):
    asd_target = rng.uniform(1e2, 1e4, (12, f_hz.size))
    asd_error = asd_target * 0.01
    mag = rng.uniform(10.0, 1000.0, (12, f_hz.size))
    _assert_png(plot_asd(tmp_path / 'a.png', f_hz, asd_target, asd_target * 0.9,
                         asd_error, OUTPUT_CHANNELS, frf_mag=mag))
    # Without the FRF overlay on one corner only: a 1 x 3 grid, and constrained layout of a
    # 12-panel log figure costs ~2 s, which one call above already covers.
    _assert_png(plot_asd(tmp_path / 'b.png', f_hz, asd_target[:3], asd_target[:3] * 0.9,
                         asd_error[:3], OUTPUT_CHANNELS[:3]))


def test_plots_for_generic_channel_names(tmp_path, rng, f_hz):
    # DAQ exports: any names and counts, units passed in instead of read from the names.
    h = rng.normal(size=(f_hz.size, 2, 7)) + 1j * rng.normal(size=(f_hz.size, 2, 7))
    names_in = [f'data[{k}]' for k in range(7)]
    _assert_png(plot_frf_matrix(tmp_path / 'm.png', f_hz, h, names_in, ['force', 'f_b'],
                                input_unit='m', output_unit='N', max_inputs=3))
    _assert_png(plot_frf_matrix(tmp_path / 'one.png', f_hz, h[:, :1, :1], ['disp'], ['force']))
    asd = rng.uniform(1.0, 10.0, (1, f_hz.size))
    _assert_png(plot_asd(tmp_path / 'a.png', f_hz, asd, asd, asd * 0.1, ['force'],
                         frf_mag=asd, units=['N'], frf_unit='N/m'))
    t = np.arange(200) / FS_HZ
    _assert_png(plot_time_overlay(tmp_path / 't.png', t, np.sin(t)[None], np.cos(t)[None],
                                  ['force'], units=['N']))
    with pytest.raises(ShapeError, match='units: expected 1 entries'):
        plot_time_overlay(tmp_path / 'u.png', t, np.sin(t)[None], np.cos(t)[None], ['force'],
                          units=['N', 'N'])
    with pytest.raises(ConfigError, match='max_inputs'):
        plot_frf_matrix(tmp_path / 'x.png', f_hz, h, names_in, ['force', 'f_b'], max_inputs=0)


def test_paired_inputs_for_any_channel_counts():
    assert paired_inputs(INPUT_CHANNELS, OUTPUT_CHANNELS) == list(range(12))
    assert paired_inputs(['a', 'b'], ['f', 'g']) == [0, 1]
    assert paired_inputs(['a'], ['f', 'g', 'h']) == [0, 0, 0]
    assert paired_inputs(['a', 'b', 'c'], ['f']) is None
    # Vehicle names pair by name whatever their order.
    assert paired_inputs(['lf_az', 'lf_ax'], ['lf_fx', 'lf_fz']) == [1, 0]


def test_plot_damage_ratio_including_zero(tmp_path):
    ratio = [0.57, 0.52, 0.93, 0.69, 0.54, 0.93, 0.99, 0.72, 0.94, 0.97, 0.0, 2.5]
    _assert_png(plot_damage_ratio(tmp_path / 'r.png', OUTPUT_CHANNELS, ratio))


def test_plot_relative_damage_spectrum(tmp_path, rng):
    target = 10.0 ** rng.uniform(14, 18, (12, 5))
    prediction = target * 10.0 ** rng.uniform(-0.5, 0.2, target.shape)
    prediction[3, 4] = 0.0
    _assert_png(plot_relative_damage_spectrum(tmp_path / 'rds.png', OUTPUT_CHANNELS,
                                              PAPER_BANDS, target, prediction))


def test_plot_relative_damage_spectrum_all_zero_is_drawn(tmp_path):
    zeros = np.zeros((12, 5))
    _assert_png(plot_relative_damage_spectrum(tmp_path / 'rds.png', OUTPUT_CHANNELS,
                                              PAPER_BANDS, zeros, zeros))


def test_plot_condition_number(tmp_path, f_hz):
    _assert_png(plot_condition_number(tmp_path / 'k.png', f_hz, 10 ** (1 + f_hz / 20)))


def test_plot_rmse_colormap_cells_take_rubric_colours(tmp_path):
    # One row, levels in reverse order left to right: bad cells are on the left while the
    # legend lists the levels left to right from perfect, so the big cells decide the mean x.
    values = [[150.0, 90.0, 60.0, 30.0, 10.0]]
    out = plot_rmse_colormap(tmp_path / 'rmse.png', ['belgian_block'],
                             ['lf_fx', 'lf_fy', 'lf_fz', 'rf_fx', 'rf_fy'], values)
    img = _rgb(out)
    mean_x = []
    for colour in RUBRIC_COLORS:
        # imshow with nearest interpolation paints exact colours; 1/255 covers PNG quantising.
        hit = np.all(np.abs(img - np.array(to_rgb(colour))) < 1.5 / 255, axis=2)
        assert hit.sum() > 1000, f'{colour} barely present'
        mean_x.append(np.nonzero(hit)[1].mean())
    assert np.all(np.diff(mean_x) < 0), mean_x


def test_plots_do_not_import_pyplot():
    code = ('import sys; import wheel_force_estimator.report.spectral_plots; '
            'import wheel_force_estimator.report.evaluation_plots; '
            'sys.exit(int("matplotlib.pyplot" in sys.modules))')
    assert subprocess.run([sys.executable, '-c', code], check=False).returncode == 0


# ---------------------------------------------------------------- plots: rejected input
def test_shape_mismatch_names_the_argument(tmp_path, rng, f_hz):
    good = rng.uniform(0, 1, (f_hz.size, 12))
    with pytest.raises(ShapeError, match='coherence_multiple'):
        plot_coherence(tmp_path / 'c.png', f_hz, good[:, :11], None, OUTPUT_CHANNELS)
    with pytest.raises(ShapeError, match='coherence_ordinary_diag'):
        plot_coherence(tmp_path / 'c.png', f_hz, good, good[1:], OUTPUT_CHANNELS)
    with pytest.raises(ShapeError, match='h: expected shape'):
        plot_frf_diagonal(tmp_path / 'f.png', f_hz, np.ones((f_hz.size, 12, 11)),
                          INPUT_CHANNELS, OUTPUT_CHANNELS)
    t_s = np.arange(100) / FS_HZ
    with pytest.raises(ShapeError, match='prediction'):
        plot_time_overlay(tmp_path / 't.png', t_s, np.zeros((12, 100)),
                          np.zeros((12, 99)), OUTPUT_CHANNELS)
    with pytest.raises(ShapeError, match='asd_prediction'):
        plot_asd(tmp_path / 'a.png', f_hz, good.T, good.T[:3], good.T, OUTPUT_CHANNELS)
    with pytest.raises(ShapeError, match='ratio'):
        plot_damage_ratio(tmp_path / 'r.png', OUTPUT_CHANNELS, np.ones(11))
    with pytest.raises(ShapeError, match='bands_hz'):
        plot_relative_damage_spectrum(tmp_path / 'd.png', OUTPUT_CHANNELS,
                                      [0.0, 2.2], np.ones((12, 1)), np.ones((12, 1)))
    with pytest.raises(ShapeError, match='rds_prediction'):
        plot_relative_damage_spectrum(tmp_path / 'd.png', OUTPUT_CHANNELS, PAPER_BANDS,
                                      np.ones((12, 5)), np.ones((12, 4)))
    with pytest.raises(ShapeError, match='rmse_pct'):
        plot_rmse_colormap(tmp_path / 'm.png', ['a', 'b'], OUTPUT_CHANNELS,
                           np.ones((3, 12)))
    with pytest.raises(ShapeError, match='cond'):
        plot_condition_number(tmp_path / 'k.png', f_hz, np.ones(3))
    with pytest.raises(ShapeError, match='duplicated'):
        plot_damage_ratio(tmp_path / 'r.png', ['lf_fx', 'lf_fx'], [1.0, 1.0])
    assert not list(tmp_path.iterdir()), 'a rejected plot still wrote a file'


def test_non_finite_is_rejected_with_argument_named(tmp_path, f_hz):
    asd = np.ones((12, f_hz.size))
    bad = asd.copy()
    bad[4, 7] = np.nan
    with pytest.raises(NonFiniteError, match=r'asd_error: .*index \(4, 7\)'):
        plot_asd(tmp_path / 'a.png', f_hz, asd, asd, bad, OUTPUT_CHANNELS)
    h = np.ones((f_hz.size, 12, 12), complex)
    h[3, 0, 0] = complex(np.inf, 0.0)
    with pytest.raises(NonFiniteError, match='h: '):
        plot_frf_diagonal(tmp_path / 'f.png', f_hz, h, INPUT_CHANNELS, OUTPUT_CHANNELS)
    with pytest.raises(NonFiniteError, match='ratio'):
        plot_damage_ratio(tmp_path / 'r.png', ['lf_fx'], [np.inf])
    with pytest.raises(NonFiniteError, match='f_hz'):
        plot_condition_number(tmp_path / 'k.png', [0.0, np.nan, 2.0], [1.0, 1.0, 1.0])


def test_invalid_arguments_are_config_errors(tmp_path, f_hz):
    cond = np.ones(f_hz.size)
    with pytest.raises(ConfigError, match='.png'):
        plot_condition_number(tmp_path / 'k.jpg', f_hz, cond)
    with pytest.raises(ConfigError, match='does not exist'):
        plot_condition_number(tmp_path / 'missing' / 'k.png', f_hz, cond)
    with pytest.raises(ConfigError, match='strictly increasing'):
        plot_condition_number(tmp_path / 'k.png', f_hz[::-1], cond)
    with pytest.raises(ConfigError, match='f_max_hz'):
        plot_coherence(tmp_path / 'c.png', f_hz, np.ones((f_hz.size, 12)), None,
                       OUTPUT_CHANNELS, f_max_hz=-1.0)
    t_s = np.arange(100) / FS_HZ
    with pytest.raises(ConfigError, match='window_s'):
        plot_time_overlay(tmp_path / 't.png', t_s, np.zeros((12, 100)),
                          np.zeros((12, 100)), OUTPUT_CHANNELS, window_s=(50.0, 60.0))
    with pytest.raises(ConfigError, match='ratio: negative value -0.5 for channel lf_fy'):
        plot_damage_ratio(tmp_path / 'r.png', ['lf_fx', 'lf_fy'], [1.0, -0.5])
    with pytest.raises(ConfigError, match='asd_target: negative value .* channel rf_fx'):
        neg = np.ones((12, f_hz.size))
        neg[3, 0] = -1.0
        plot_asd(tmp_path / 'a.png', f_hz, neg, neg, neg, OUTPUT_CHANNELS)


# ---------------------------------------------------------------- tables
CH3 = ['lf_fx', 'lf_fy', 'lf_fz']


def test_rubric_index_boundaries_follow_the_paper():
    # perfect < 25, great < 50, good < 75, bad < 100, else not qualified.
    pct = [0.0, 24.99, 25.0, 49.99, 50.0, 74.99, 75.0, 99.99, 100.0, 1e6]
    assert rubric_levels(pct) == ['perfect', 'perfect', 'great', 'great', 'good', 'good',
                                  'bad', 'bad', 'not_qualified', 'not_qualified']


def rubric_levels(pct):
    return [tables.RUBRIC_NAMES[i] for i in tables.rubric_index(pct)]


def test_rubric_agrees_with_core_metrics():
    metrics = pytest.importorskip('wheel_force_estimator.core.metrics')
    pct = [0.0, 12.0, 24.999, 25.0, 37.0, 50.0, 74.9, 75.0, 99.9, 100.0, 250.0]
    assert rubric_levels(pct) == [metrics.rubric(v) for v in pct]
    assert tuple(metrics.RUBRIC_LEVELS) == tables.RUBRIC_NAMES


def test_rmse_table_text():
    text = tables.rmse_table(CH3, [21.34, 54.6, 100.0], [18.0, 50.04, 99.94],
                             ['perfect', 'good', 'not_qualified'])
    assert text == (
        'channel  RMSE %  RMSE HP1 %  rubric\n'
        '-------  ------  ----------  -------------\n'
        'lf_fx      21.3        18.0  perfect\n'
        'lf_fy      54.6        50.0  good\n'
        'lf_fz     100.0        99.9  not_qualified')


def test_rmse_table_markdown_without_high_pass():
    text = tables.rmse_table(CH3, [21.34, 54.6, 100.0], None,
                             ['perfect', 'good', 'not_qualified'], markdown=True)
    assert text == (
        '| channel | RMSE % | rubric        |\n'
        '|:--------|-------:|:--------------|\n'
        '| lf_fx   |   21.3 | perfect       |\n'
        '| lf_fy   |   54.6 | good          |\n'
        '| lf_fz   |  100.0 | not_qualified |')


def test_rmse_table_rejects_bad_input():
    with pytest.raises(ShapeError, match='rmse_hp_pct'):
        tables.rmse_table(CH3, [1, 2, 3], [1, 2], ['perfect'] * 3)
    with pytest.raises(ShapeError, match='rubric'):
        tables.rmse_table(CH3, [1, 2, 3], None, ['perfect'] * 2)
    with pytest.raises(ConfigError, match="'superb' for channel lf_fy"):
        tables.rmse_table(CH3, [1, 2, 3], None, ['perfect', 'superb', 'good'])
    with pytest.raises(NonFiniteError, match='rmse_pct'):
        tables.rmse_table(CH3, [1, np.nan, 3], None, ['perfect'] * 3)


def test_damage_table_matches_paper_table_3_rows():
    # First two rows of paper Table 3 plus a channel whose target has no damage at all.
    text = tables.damage_table(CH3, [2.78e17, 8.04e16, 0.0], [1.59e17, 4.18e16, 3.0],
                               [1.59 / 2.78, 4.18 / 8.04, np.inf])
    assert text == (
        'ch  channel  target damage  prediction damage  pred/target  verdict (0.5-2)\n'
        '--  -------  -------------  -----------------  -----------  ---------------\n'
        ' 1  lf_fx         2.78e+17           1.59e+17         0.57  good\n'
        ' 2  lf_fy         8.04e+16           4.18e+16         0.52  good\n'
        ' 3  lf_fz         0.00e+00           3.00e+00          n/a  n/a')


def test_damage_table_verdicts_and_rejections():
    md = tables.damage_table(CH3, [1.0, 1.0, 1.0], [0.3, 1.0, 2.5], [0.3, 1.0, 2.5],
                             markdown=True)
    assert md.splitlines()[2:] == ['|  1 | lf_fx   |      1.00e+00 |          3.00e-01 |'
                                   '        0.30 | low             |',
                                   '|  2 | lf_fy   |      1.00e+00 |          1.00e+00 |'
                                   '        1.00 | good            |',
                                   '|  3 | lf_fz   |      1.00e+00 |          2.50e+00 |'
                                   '        2.50 | high            |']
    with pytest.raises(NonFiniteError, match='ratio'):
        # An infinite ratio is only accepted where the target damage is exactly 0.
        tables.damage_table(CH3, [1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, np.inf, 1.0])
    with pytest.raises(ConfigError, match='prediction: negative value -1.0 for channel lf_fz'):
        tables.damage_table(CH3, [1.0, 1.0, 1.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0])


def test_event_table():
    text = tables.event_table(['twist', 'belgian_block'], CH3, [[1, 2, 3], [100.26, 4.44, 0]])
    assert text == (
        'event          lf_fx  lf_fy  lf_fz\n'
        '-------------  -----  -----  -----\n'
        'twist            1.0    2.0    3.0\n'
        'belgian_block  100.3    4.4    0.0')
    with pytest.raises(ShapeError, match=r'values: expected shape \(2, 3\)'):
        tables.event_table(['twist', 'belgian_block'], CH3, np.ones((3, 2)))


def test_rubric_counts_table_reproduces_paper_table_2_counts():
    counts = {'perfect': 59, 'great': 75, 'good': 27, 'bad': 6, 'not_qualified': 13}
    text = tables.rubric_counts_table(counts, markdown=True)
    # 59/180 = 32.8 -> 33, 75/180 = 41.7 -> 42, 27/180 = 15.0, 6/180 = 3.3, 13/180 = 7.2.
    assert text == (
        '| rubric        | RMSE range | count | share % |\n'
        '|:--------------|:-----------|------:|--------:|\n'
        '| perfect       | 0-25 %     |    59 |      33 |\n'
        '| great         | 25-50 %    |    75 |      42 |\n'
        '| good          | 50-75 %    |    27 |      15 |\n'
        '| bad           | 75-100 %   |     6 |       3 |\n'
        '| not_qualified | >= 100 %   |    13 |       7 |')
    assert tables.rubric_counts_table({}).splitlines()[2].split() == [
        'perfect', '0-25', '%', '0', '-']
    with pytest.raises(ConfigError, match='excellent'):
        tables.rubric_counts_table({'excellent': 1})
    with pytest.raises(ConfigError, match='bad must be a non-negative integer'):
        tables.rubric_counts_table({'bad': -1})


# ---------------------------------------------------------------- markdown report
def test_report_writer_links_images_relatively(tmp_path, f_hz):
    report = ReportWriter(tmp_path / 'out' / 'report')
    assert report.directory.is_dir()
    png = plot_condition_number(report.path('cond.png'), f_hz, np.ones(f_hz.size))
    (report.directory / 'plots').mkdir()
    nested = plot_condition_number(report.directory / 'plots' / 'my cond.png', f_hz,
                                   np.ones(f_hz.size))
    report.heading('Fit report', 1)
    report.paragraph('Two segments, 512 Hz.')
    report.table(tables.rubric_counts_table({'perfect': 1}, markdown=True))
    report.image(png, 'Condition number')
    report.image(nested, 'Nested  plot\nwith space')
    out = report.write()
    assert out == report.directory / 'report.md'
    text = out.read_text(encoding='utf-8')
    assert text.startswith('# Fit report\n\nTwo segments, 512 Hz.\n\n| rubric ')
    assert '![Condition number](cond.png)\n\n*Condition number*' in text
    assert '![Nested plot with space](<plots/my cond.png>)' in text
    assert str(tmp_path) not in text, 'links must be relative'
    assert not list(report.directory.glob('*.tmp'))


def test_report_writer_rejects_bad_use(tmp_path):
    a_file = tmp_path / 'taken'
    a_file.write_text('x')
    with pytest.raises(ConfigError, match='not a directory'):
        ReportWriter(a_file)
    report = ReportWriter(tmp_path / 'r')
    with pytest.raises(ConfigError, match='does not exist'):
        report.image(tmp_path / 'r' / 'missing.png', 'Missing')
    with pytest.raises(ConfigError, match='level'):
        report.heading('Too deep', 7)
    with pytest.raises(ConfigError, match='plain file name'):
        report.write('../escape.md')
