"""read_csv and Trace: the library's reader, its errors as Python's."""

import os
import warnings

import numpy as np
import pytest

import mckibben
from conftest import STAIR


def test_the_stair_reads_as_the_command_reads_it(stair):
    assert len(stair) == 4000
    assert stair.dt == pytest.approx(0.01)
    assert (stair.time_name, stair.input_name, stair.output_name) == ("t", "pressure", "displacement")
    assert stair.input.dtype == np.float64 and stair.output.shape == (4000,)
    assert stair.source == str(STAIR)


def test_a_file_of_other_column_names_keeps_them(tmp_path):
    f = tmp_path / "rig.csv"
    f.write_text("time_s,p_kPa,x_mm\n0,100,1\n0.1,200,2\n0.2,300,3\n")
    trace = mckibben.read_csv(f, time="time_s", input="p_kPa", output="x_mm")
    assert (trace.time_name, trace.input_name, trace.output_name) == ("time_s", "p_kPa", "x_mm")


def test_a_file_without_a_time_column_reads_with_dt(stair, tmp_path):
    f = tmp_path / "untimed.csv"
    f.write_text("p_kPa,x_mm\n100,1\n200,2\n300,3\n")
    trace = mckibben.read_csv(f, input="p_kPa", output="x_mm", dt=0.5)
    assert list(trace.t) == [0.0, 0.5, 1.0] and trace.dt == 0.5
    assert list(trace.output) == [1.0, 2.0, 3.0]
    with pytest.raises(ValueError, match=r"no time column \"t\".*`dt=SECONDS`"):
        mckibben.read_csv(f, input="p_kPa", output="x_mm")
    # A clock named beside dt is refused, as --time beside --dt.
    with pytest.raises(ValueError, match="^time and dt exclude each other"):
        mckibben.read_csv(STAIR, time="t", dt=0.01)
    # The fix in Python's words (it read "(`time` t, without `dt`)").
    with pytest.raises(ValueError, match=r'this file has one, "t": read its clock instead \(`time="t"`, without `dt`\)'):
        mckibben.read_csv(STAIR, dt=0.01)
    with pytest.raises(ValueError, match="dt must be a positive number of seconds"):
        mckibben.read_csv(f, input="p_kPa", output="x_mm", dt=-1.0)


def test_a_trace_from_arrays_takes_its_column_names(stair):
    u, y = stair.input[:100], stair.output[:100]
    trace = mckibben.Trace(u, y, stair.dt, input_name="p_kPa", output_name="x_mm", time_name="time_s")
    assert (trace.time_name, trace.input_name, trace.output_name) == ("time_s", "p_kPa", "x_mm")
    assert mckibben.Trace(u, y, stair.dt).time_name == "t"
    with pytest.raises(ValueError, match='time_name and input_name are both "p"'):
        mckibben.Trace(u, y, stair.dt, input_name="p", time_name="p")
    with pytest.raises(ValueError, match="output_name is empty"):
        mckibben.Trace(u, y, stair.dt, output_name=" ")


def test_file_errors_name_the_file_line_and_column(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        mckibben.read_csv(tmp_path / "nope.csv")
    with pytest.raises(ValueError, match='no input column "valve".*choose another with `input=COL`, here one of "valve_in", "valve_out"'):
        mckibben.read_csv(STAIR, input="valve")
    bad = tmp_path / "bad.csv"
    bad.write_text("t,pressure,displacement\n0,0.1,1\n0.1,nan,2\n0.2,0.1,3\n")
    with pytest.raises(ValueError, match=r'line 3, column "pressure": "nan" is not finite'):
        mckibben.read_csv(bad)
    gap = tmp_path / "gap.csv"
    rows = [f"{k * 0.1:.1f},{k % 3},{k}" for k in range(60) if k != 30]
    gap.write_text("t,pressure,displacement\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match="non-uniform time base"):
        mckibben.read_csv(gap)
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        pieces = mckibben.read_csv(gap, split_gaps=True)
    assert [len(p) for p in pieces] == [30, 29]
    assert any("`split_gaps` cut here" in str(n.message) for n in notes)
    assert len(mckibben.read_csv(gap, resample=0.1)) == 60
    # Both: cut only where the clock runs back, each piece across its gap.
    back = tmp_path / "back.csv"
    rows = [f"{k * 0.1 - (3.5 if k >= 40 else 0):.1f},{k % 3},{k}" for k in range(80) if k != 30]
    back.write_text("t,pressure,displacement\n" + "\n".join(rows) + "\n")
    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always")
        pieces = mckibben.read_csv(back, resample=0.1, split_gaps=True)
    assert [len(p) for p in pieces] == [40, 40]
    assert pieces[1].t[0] == pytest.approx(0.5)
    assert any("time runs back" in str(n.message) for n in notes)
    with pytest.raises(ValueError, match="resample must be a positive"):
        mckibben.read_csv(gap, resample=-1.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"input": "t"}, 'time and input are both "t"'),
        ({"output": "t"}, 'time and output are both "t"'),
        ({"output": "pressure"}, 'input and output are both "pressure"'),
        ({"time": "displacement"}, 'time and output are both "displacement"'),
    ],
)
def test_two_arguments_naming_one_column_are_refused(kwargs, message):
    # The reader read the one column twice: input="t" gave the time as input.
    with pytest.raises(ValueError, match=f"^{message}: each must name a column of its own"):
        mckibben.read_csv(STAIR, **kwargs)


def test_a_trace_takes_any_float_dtype_layout_or_list():
    u = np.linspace(0, 1, 50)
    y = 2 * u
    a = mckibben.Trace(u, y, 0.1)
    b = mckibben.Trace(u.astype(np.float32).tolist(), np.asfortranarray(y[::-1])[::-1], 0.1)
    assert np.array_equal(a.output, b.output)
    assert np.array_equal(b.input, u.astype(np.float32).astype(np.float64))
    assert a.t[-1] == pytest.approx(4.9)


@pytest.mark.parametrize(
    "u, y, dt, error, message",
    [
        # Named as Trace's arguments: input, output.
        ([], [], 0.1, ValueError, "^input is empty"),
        ([1.0, np.nan], [1.0, 2.0], 0.1, ValueError, r"^input\[1\] is NaN"),
        ([1.0, 2.0], [1.0, np.inf], 0.1, ValueError, r"^output\[1\] is inf"),
        ([1.0, 2.0], [1.0, 2.0, 3.0], 0.1, ValueError, "^input and output differ in length"),
        # Text or None where an array goes is the wrong type, not a value.
        ("ab", [1.0, 2.0], 0.1, TypeError, r"^input must be an array of numbers \(a NumPy array or a list\), got str 'ab'"),
        ([1.0, 2.0], None, 0.1, TypeError, "^output must be an array of numbers .*, got None"),
        (b"ab", [1.0, 2.0], 0.1, TypeError, "^input must be an array of numbers .*, got bytes b'ab'"),
        ({"a": 1}, [1.0, 2.0], 0.1, TypeError, "^input must be an array of numbers .*, got dict"),
        ([[1.0, 2.0]], [1.0, 2.0], 0.1, ValueError, "one-dimensional"),
        ([1.0, 2.0], [1.0, 2.0], 0.0, ValueError, "dt must be a positive"),
        # A step whose last time is infinite.
        ([1.0, 2.0], [1.0, 2.0], float("inf"), ValueError, "^dt must be a positive number of seconds, got inf"),
        # As the commands' --dt: a nanosecond to a day.
        ([1.0, 2.0], [1.0, 2.0], 1e300, ValueError, r"^dt: 1e300 s is outside a nanosecond to a day"),
        ([1.0, 2.0], [1.0, 2.0], 1e-12, ValueError, r"^dt: 1e-12 s is outside a nanosecond to a day"),
        (["a", "b"], [1.0, 2.0], 0.1, TypeError, "expected real numbers"),
        ([1j, 2j], [1.0, 2.0], 0.1, TypeError, "complex"),
        ([True, False], [1.0, 2.0], 0.1, TypeError, "bool"),
    ],
)
def test_bad_arrays_raise_the_named_exception(u, y, dt, error, message):
    with pytest.raises(error, match=message):
        mckibben.Trace(u, y, dt)


@pytest.mark.parametrize(
    "call, message",
    [
        # PyO3 names an argument it cannot convert only in a note on the
        # exception: the message itself names it here.
        (lambda: mckibben.Trace([1.0, 2.0], [1.0, 2.0], "0.1"), r"^dt must be a number \(an int or a float\), got str '0.1'"),
        (lambda: mckibben.Trace([1.0, 2.0], [1.0, 2.0], 0.1, input_name=1), "^input_name must be a str, got int 1"),
        (lambda: mckibben.Trace([1.0, 2.0], [1.0, 2.0], 0.1, source=None), "^source must be a str, got None"),
        (lambda: mckibben.read_csv(STAIR, resample="0.01"), "^resample must be a number .*, got str '0.01'"),
        (lambda: mckibben.read_csv(STAIR, split_gaps=1), "^split_gaps must be True or False, got int 1"),
        (lambda: mckibben.read_csv(STAIR, time=3), "^time must be a str, got int 3"),
        (lambda: mckibben.read_csv(3), r"^path must be a file's path \(a str, bytes or os.PathLike\), got int 3"),
    ],
)
def test_a_value_of_the_wrong_type_names_its_argument(call, message):
    with pytest.raises(TypeError, match=message):
        call()


def test_a_bool_is_not_a_number():
    # Taken as 1, `dt=True` made a trace of 1 s steps.
    with pytest.raises(TypeError, match="^dt must be a number .*, got bool True"):
        mckibben.Trace([1.0, 2.0], [1.0, 2.0], True)
    with pytest.raises(TypeError, match="^resample must be a number .*, got bool True"):
        mckibben.read_csv(STAIR, resample=True)


def test_a_path_may_be_bytes_as_open_takes_it(tmp_path):
    # read_csv's own message listed bytes, yet refused them.
    trace = mckibben.read_csv(os.fsencode(STAIR))
    assert len(trace) == 4000 and trace.source == str(STAIR)
    # Decoded as os.fsdecode does: a name that is not UTF-8 reads too.
    name = os.fsencode(tmp_path) + b"/caf\xe9.csv"
    with open(name, "w") as f:
        f.write("t,pressure,displacement\n0,0.1,1\n0.1,0.2,2\n")
    assert len(mckibben.read_csv(name)) == 2


def test_a_path_with_two_dashes_is_named_as_given(tmp_path):
    # The flags' renaming to keywords rewrote `run--time` as run`time`.
    missing = tmp_path / "run--time" / "missing.csv"
    with pytest.raises(FileNotFoundError) as raised:
        mckibben.read_csv(missing)
    assert str(missing) in str(raised.value)


class _Raises:
    """An array-like (as a pandas column is) or a number whose conversion
    raises `error`, as Ctrl-C or an exhausted memory raises it there."""

    def __init__(self, error):
        self.error = error

    def __array__(self, dtype=None, copy=None):
        raise self.error

    def __float__(self):
        raise self.error


@pytest.mark.parametrize("error", [KeyboardInterrupt, MemoryError])
def test_an_interrupt_while_an_argument_converts_reaches_the_caller(error):
    # It was a ValueError ("not an array of numbers") and a TypeError ("dt
    # must be a number"): a Ctrl-C read as a wrong argument.
    u = np.linspace(0.0, 0.4, 100)
    with pytest.raises(error):
        mckibben.Trace(_Raises(error), u, 0.01)
    with pytest.raises(error):
        mckibben.Trace(u, u, _Raises(error))
    # Any other error of the conversion is the argument's.
    with pytest.raises(ValueError, match="not an array of numbers"):
        mckibben.Trace(_Raises(RuntimeError("broken")), u, 0.01)


def test_a_file_that_cannot_be_read_raises_open_s_exception(tmp_path):
    # A folder read as a file was a plain OSError, which `except
    # IsADirectoryError` missed; the errno is set, as open() sets it.
    with pytest.raises(IsADirectoryError) as raised:
        mckibben.read_csv(tmp_path)
    assert raised.value.errno == 21 and str(tmp_path) in str(raised.value)
    with pytest.raises(IsADirectoryError):
        mckibben.Model.load(tmp_path)
    with pytest.raises(FileNotFoundError) as raised:
        mckibben.read_csv(tmp_path / "missing.csv")
    assert raised.value.errno == 2
    # `filename` set, as `open` sets it (it read None).
    assert raised.value.filename == str(tmp_path / "missing.csv")
    assert raised.value.strerror == "No such file or directory"
