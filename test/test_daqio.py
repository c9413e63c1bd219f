# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The neutral generic-recording reader (``daqio``) and the diagnosis façade over it."""
import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.errors import RecordingError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.daqio import check_specs
from wheel_force_estimator.daqio import DaqRecording
from wheel_force_estimator.daqio import parse_spec
from wheel_force_estimator.daqio import quantity_of_unit
from wheel_force_estimator.daqio import read_daq
from wheel_force_estimator.diagnosis import MotionRecording
from wheel_force_estimator.diagnosis.generic import load_generic
from wheel_force_estimator.diagnosis.generic import parse_spec as diagnosis_parse_spec

ROOT = Path(__file__).resolve().parents[1]
IN = [parse_spec('x:acceleration:g', 'input')]
OUT = [parse_spec('f:force:lbf', 'output')]


def test_recording_error_is_neutral():
    assert issubclass(RecordingError, WheelForceError)
    assert issubclass(RecordingError, ValueError)
    assert not issubclass(RecordingError, DiagnosisError)


def test_spec_errors_are_recording_errors_and_diagnosis_errors_in_the_facade():
    with pytest.raises(RecordingError, match='unknown velocity unit') as neutral:
        parse_spec('v:velocity:knots', 'input')
    with pytest.raises(DiagnosisError) as facade:
        diagnosis_parse_spec('v:velocity:knots', 'input')
    assert str(facade.value) == str(neutral.value)
    with pytest.raises(RecordingError, match='role must be one of'):
        parse_spec('v:velocity:m/s', 'motion')


def test_spec_text_and_si_quantities():
    spec = parse_spec('data[3]:velocity:mm/s', 'input')
    assert spec.text == 'data[3]:velocity:mm/s'
    assert spec.scale == pytest.approx(1e-3)
    assert quantity_of_unit('m') == 'displacement'
    assert quantity_of_unit('m/s') == 'velocity'
    assert quantity_of_unit('m/s^2') == 'acceleration'
    assert quantity_of_unit('m/s2') == 'acceleration'
    assert quantity_of_unit('N') == 'force'
    assert quantity_of_unit('mm') is None


def test_check_specs():
    x = parse_spec('x:displacement:m', 'input')
    f = parse_spec('f:force:N', 'output')
    assert check_specs([x], [f]) == ((x,), (f,))
    with pytest.raises(RecordingError, match='at least one --input and one --output'):
        check_specs([x], [])
    with pytest.raises(RecordingError, match="output channel 'f' is declared twice"):
        check_specs([x], [f, f])
    with pytest.raises(RecordingError, match='share one quantity'):
        check_specs([x, parse_spec('y:velocity:m/s', 'input')], [f])
    with pytest.raises(RecordingError, match='motion and outputs force'):
        check_specs([f], [f])


def test_read_converts_units_and_gives_stamps(tmp_path):
    (tmp_path / 'a.csv').write_text('x,f\n1.0,2.0\n0.5,-1.0\n0.0,0.0\n')
    rec = read_daq(tmp_path / 'a.csv', IN, OUT, 1024.0)
    np.testing.assert_allclose(rec.inputs, [[9.80665, 4.903325, 0.0]], rtol=1e-15)
    np.testing.assert_allclose(rec.outputs, [[2 * 4.4482216152605, -4.4482216152605, 0.0]],
                               rtol=1e-15)
    assert rec.input_quantity == 'acceleration' and rec.input_unit == 'm/s^2'
    assert rec.input_channels == ('x',) and rec.output_channels == ('f',)
    # 1 / 1024 s = 976562.5 ns: rounded, never truncated to a drifting grid.
    np.testing.assert_array_equal(rec.stamp_ns(), [0, 976562, 1953125])
    assert rec.duration_s == pytest.approx(3 / 1024)
    assert not rec.inputs.flags.writeable
    motion = load_generic(tmp_path / 'a.csv', IN, OUT, 1024.0)
    assert isinstance(motion, MotionRecording)
    np.testing.assert_array_equal(motion.inputs, rec.inputs)


def test_reader_refuses_instead_of_repairing(tmp_path):
    (tmp_path / 'empty.csv').write_text('x,f\n')
    with pytest.raises(RecordingError, match='empty.csv: no samples'):
        read_daq(tmp_path / 'empty.csv', IN, OUT, 100.0)
    (tmp_path / 'a.csv').write_text('x,f\n1,2\n')
    for fs in (0.0, -1.0, float('nan')):
        with pytest.raises(RecordingError, match='a.csv: sample rate'):
            read_daq(tmp_path / 'a.csv', IN, OUT, fs)
    np.savez(tmp_path / 'o.npz', x=np.array(['a', 'b']), f=np.ones(2))
    with pytest.raises(RecordingError, match="channel 'x' is not numeric"):
        read_daq(tmp_path / 'o.npz', IN, OUT, 100.0)
    (tmp_path / 'b.mat').write_bytes(b'not a mat file at all')
    with pytest.raises(RecordingError, match='b.mat: cannot read MAT file'):
        read_daq(tmp_path / 'b.mat', IN, OUT, 100.0)
    with pytest.raises(RecordingError, match='unequal|input samples but'):
        DaqRecording('r', 10.0, np.zeros((1, 3)), np.zeros((1, 2)), ('x',), ('f',),
                     'displacement')
    with pytest.raises(RecordingError, match="input quantity 'force'"):
        DaqRecording('r', 10.0, np.zeros((1, 3)), np.zeros((1, 3)), ('x',), ('f',), 'force')


def test_daqio_imports_without_ros_or_matplotlib():
    script = (
        'import sys\n'
        'class Block:\n'
        "    BLOCKED = ('rclpy', 'matplotlib', 'rosbags', 'yaml')\n"
        '    def find_spec(self, name, path=None, target=None):\n'
        "        if name.split('.')[0] in self.BLOCKED:\n"
        "            raise ImportError(f'blocked: {name}')\n"
        'sys.meta_path.insert(0, Block())\n'
        'import wheel_force_estimator.daqio.reader\n'
        "leaked = [m for m in sys.modules if m.split('.')[0] in Block.BLOCKED]\n"
        'assert not leaked, leaked\n')
    proc = subprocess.run([sys.executable, '-c', script], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_text_tables_as_daq_software_exports_them(tmp_path):
    # A European export: comment, metadata, names, units; ';' separators, decimal commas.
    (tmp_path / 'rig.csv').write_text(
        '# exported by the rig controller\n'
        'Sample rate;1024 Hz\n'
        '1024\n'
        'Time;x;f\n'
        's;g;lbf\n'
        '0,000;1,5;-2,25\n'
        '\n'
        '0,001;0,5;1e1\n')
    rec = read_daq(tmp_path / 'rig.csv', IN, OUT, 1024.0)
    np.testing.assert_allclose(rec.inputs[0], np.array([1.5, 0.5]) * 9.80665, rtol=1e-15)
    np.testing.assert_allclose(rec.outputs[0], np.array([-2.25, 10.0]) * 4.4482216152605,
                               rtol=1e-15)
    # Tab-separated with decimal points; a units row under the names.
    (tmp_path / 'rig.tsv').write_text('x\tf\ng\tlbf\n1.5\t-2.25\n0.5\t10\n')
    np.testing.assert_array_equal(read_daq(tmp_path / 'rig.tsv', IN, OUT, 1024.0).inputs,
                                  rec.inputs)
    # White space, no header: columns by number; ';' with decimal points is not comma-read.
    (tmp_path / 'rig.txt').write_text('% ASCII export\n  1.5   -2.25\n  0.5   10\n')
    cols = [parse_spec('0:acceleration:g', 'input')], [parse_spec('1:force:lbf', 'output')]
    np.testing.assert_array_equal(read_daq(tmp_path / 'rig.txt', *cols, 1024.0).outputs,
                                  rec.outputs)
    (tmp_path / 'point.csv').write_text('x;f\n1.5;-2.25\n0.5;10\n')
    np.testing.assert_array_equal(read_daq(tmp_path / 'point.csv', IN, OUT, 1024.0).outputs,
                                  rec.outputs)


@pytest.mark.parametrize('name, text, match', [
    ('a.csv', 'x;f\ng;lbf\n1,5;2\n0,5;overload\n',
     r'a\.csv: non-numeric value on line 4: .0,5;overload.'),
    ('b.txt', '1 2\n3 4\n5\n', 'line 3 has 1 fields, the table 2 columns'),
    ('c.csv', '# only a comment\n', 'empty text table'),
    ('d.csv', 'x,f\n', r'd\.csv: no samples'),
])
def test_text_tables_name_the_bad_line(tmp_path, name, text, match):
    (tmp_path / name).write_text(text)
    with pytest.raises(RecordingError, match=match):
        read_daq(tmp_path / name, IN, OUT, 100.0)


def _mat73(path, arrays, struct=None):
    """Write a file laid out as MATLAB's save -v7.3 writes it (HDF5, 512-byte header)."""
    import h5py  # a dependency of the package (setup.py): fail, never skip, when missing
    with h5py.File(path, 'w', userblock_size=512) as fh:
        for name, value in arrays.items():
            # MATLAB is column-major: an n x k array is stored as k x n
            fh.create_dataset(name, data=np.asarray(value).T)
            fh[name].attrs['MATLAB_class'] = np.bytes_('double')
        if struct:
            grp = fh.create_group(struct[0])
            grp.attrs['MATLAB_class'] = np.bytes_('struct')
            for name, value in struct[1].items():
                grp.create_dataset(name, data=np.asarray(value).T)
                grp[name].attrs['MATLAB_class'] = np.bytes_('double')
        fh.create_dataset('label', data=np.frombuffer(b'r\0i\0g\0', np.uint16))
        fh['label'].attrs['MATLAB_class'] = np.bytes_('char')
    text = b'MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Thu Nov 26 12:00:00 2026 HDF5'
    header = text.ljust(116, b' ') + b'\0' * 8 + b'\x00\x02' + b'IM'
    with open(path, 'r+b') as fh:
        fh.write(header)


def test_matlab_v73_files_are_read(tmp_path):
    from scipy.io.matlab import matfile_version
    x = np.array([1.0, 0.5, 0.0])
    f = np.array([2.0, -1.0, 0.0])
    _mat73(tmp_path / 'r.mat', {'x': x[:, None], 'table': np.column_stack([x, f])},
           struct=('run', {'force': f[:, None]}))
    assert matfile_version(str(tmp_path / 'r.mat'))[0] == 2
    rec = read_daq(tmp_path / 'r.mat', IN, [parse_spec('table[1]:force:lbf', 'output')], 100.0)
    np.testing.assert_allclose(rec.inputs[0], x * 9.80665, rtol=1e-15)
    np.testing.assert_allclose(rec.outputs[0], f * 4.4482216152605, rtol=1e-15)
    rec = read_daq(tmp_path / 'r.mat', IN, [parse_spec('run.force:force:lbf', 'output')], 100.0)
    np.testing.assert_allclose(rec.outputs[0], f * 4.4482216152605, rtol=1e-15)
    with pytest.raises(RecordingError, match=r"no channel 'label' \(has: run.force, table, x\)"):
        read_daq(tmp_path / 'r.mat', [parse_spec('label:acceleration:g', 'input')], OUT, 100.0)


def test_matlab_struct_fields_are_channels(tmp_path):
    import scipy.io
    x = np.array([1.0, 0.5, 0.0])
    f = np.array([2.0, -1.0, 0.0])
    scipy.io.savemat(tmp_path / 's.mat', {'run': {'x': x[:, None], 'meta': {'f': f[:, None]}}})
    rec = read_daq(tmp_path / 's.mat', [parse_spec('run.x:acceleration:g', 'input')],
                   [parse_spec('run.meta.f:force:lbf', 'output')], 100.0)
    np.testing.assert_allclose(rec.inputs[0], x * 9.80665, rtol=1e-15)
    np.testing.assert_allclose(rec.outputs[0], f * 4.4482216152605, rtol=1e-15)
    with pytest.raises(RecordingError, match="'run' is not numeric"):
        read_daq(tmp_path / 's.mat', [parse_spec('run:acceleration:g', 'input')], OUT, 100.0)


def test_channels_stored_as_rows_and_nested_json(tmp_path):
    x = np.array([1.0, 0.5, 0.0, 0.25])
    f = np.array([2.0, -1.0, 0.0, 3.0])
    np.savez(tmp_path / 'rows.npz', data=np.stack([x, f]))  # 2 channels x 4 samples
    spec = [parse_spec('data[0]:acceleration:g', 'input')], [
        parse_spec('data[1]:force:lbf', 'output')]
    by_rows = read_daq(tmp_path / 'rows.npz', *spec, 100.0)
    np.savez(tmp_path / 'cols.npz', data=np.stack([x, f], axis=1))  # 4 samples x 2 channels
    by_cols = read_daq(tmp_path / 'cols.npz', *spec, 100.0)
    np.testing.assert_array_equal(by_rows.inputs, by_cols.inputs)
    np.testing.assert_array_equal(by_rows.outputs, by_cols.outputs)
    np.testing.assert_allclose(by_rows.inputs[0], x * 9.80665, rtol=1e-15)
    (tmp_path / 'n.json').write_text(json.dumps({'run': {'x': x.tolist(), 'f': f.tolist()}}))
    nested = read_daq(tmp_path / 'n.json', [parse_spec('run.x:acceleration:g', 'input')],
                      [parse_spec('run.f:force:lbf', 'output')], 100.0)
    np.testing.assert_array_equal(nested.outputs, by_cols.outputs)
