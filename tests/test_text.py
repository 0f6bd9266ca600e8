"""Durations read in sensible units."""

import pytest

from rrt_pin.core.text import duration


@pytest.mark.parametrize(
    "seconds, text",
    [
        (62.5, "62.5 s"),
        (0.00042, "420 µs"),
        (0.42, "420 ms"),
        (1.0, "1 s"),
        (210.0, "3.5 min"),
        (7560.0, "2.1 h"),
        (86400.0 * 1234, "1,234 d"),
        (1e-9, "0.001 µs"),
        (float("inf"), "inf s"),
    ],
)
def test_duration(seconds, text):
    assert duration(seconds) == text


def test_no_exponent_for_any_run_length():
    for exponent in range(-9, 9):
        for mantissa in (1.0, 2.5, 9.99):
            assert "e" not in duration(mantissa * 10.0**exponent)


def test_long_name_lists_are_cut_with_their_count():
    from rrt_pin.core.text import names

    assert names(["a", "b"]) == "a, b"
    assert (
        names([f"q{i}" for i in range(3000)]) == "q0, q1, q2, q3, q4, q5, q6, q7, … (3,000 names)"
    )
    assert names(list("abcd"), limit=2, sep=",") == "a,b,… (4 names)"


def test_arguments_are_spelled_as_the_caller_wrote_them():
    from rrt_pin.core.text import argument, cli_spelling

    assert argument("rtol") == "rtol" and argument("zmq_url") == "zmq_url"
    with cli_spelling():
        assert argument("rtol") == "--rtol" and argument("zmq_url") == "--zmq-url"
        assert argument("path", "--plot") == "--plot"
    assert argument("path", "--plot") == "path"


def test_a_library_message_names_the_argument_and_the_cli_the_flag(capsys):
    from rrt_pin.cli.app import main
    from rrt_pin.core.errors import InputError
    from rrt_pin.viewer.keyframes import keyframe_times

    with pytest.raises(InputError) as info:
        keyframe_times(1e300, 30.0)
    assert "lower fps or shorten the motion" in str(info.value) and "--fps" not in str(info.value)
    assert main(["view", "--set", "Tp=1e300", "--serve-for", "0"]) == 2
    assert "lower --fps or shorten the motion" in capsys.readouterr().err
