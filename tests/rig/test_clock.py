"""Virtual time: sequential sleeps add up; devices working at once overlap."""

import threading

import pytest

from rig.clock import RealClock, VirtualClock


def _in_threads(*bodies) -> None:
    threads = [threading.Thread(target=body) for body in bodies]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=10)


def test_sleeps_outside_a_parallel_section_add_up():
    clock = VirtualClock(start=5.0)
    _in_threads(lambda: clock.sleep(0.5), lambda: clock.sleep(0.25))
    clock.sleep(0.125)
    assert clock.now() == pytest.approx(5.875)


def test_threads_sleeping_together_advance_the_clock_to_the_latest_deadline():
    clock = VirtualClock(start=2.0)
    seen = {}

    def camera(name, *sleeps):
        def body():
            for seconds in sleeps:
                clock.sleep(seconds)
            seen[name] = clock.now()

        return body

    with clock.parallel():
        _in_threads(camera("a", 0.5), camera("b", 0.25, 0.25, 0.25), camera("c", 0.125))
        assert clock.now() == pytest.approx(2.0)  # this thread has not waited yet
    assert seen == pytest.approx({"a": 2.5, "b": 2.75, "c": 2.125})  # each on its own time
    assert clock.now() == pytest.approx(2.75)  # not the 1.375 s sum
    clock.sleep(1.0)  # after the section: sequential again, from the latest deadline
    assert clock.now() == pytest.approx(3.75)


def test_lanes_let_one_thread_serve_several_devices():
    clock = VirtualClock()
    stamps = []
    with clock.parallel():
        for camera, exposure in (("cam0", 0.25), ("cam1", 0.5), ("cam0", 0.125)):
            with clock.lane(camera):
                stamps.append(clock.now())  # when this camera starts exposing
                clock.sleep(exposure)
    assert stamps == pytest.approx([0.0, 0.0, 0.25])  # cam0's second frame follows its first
    assert clock.now() == pytest.approx(0.5)


def test_nested_sections_are_one_section():
    clock = VirtualClock()
    with clock.parallel():
        _in_threads(lambda: clock.sleep(1.0))
        with clock.parallel():
            _in_threads(lambda: clock.sleep(0.5))
    assert clock.now() == pytest.approx(1.0)


def test_a_negative_sleep_is_refused():
    with pytest.raises(ValueError, match="must be ≥ 0"):
        VirtualClock().sleep(-1.0)


def test_real_time_sections_change_nothing():
    clock = RealClock()
    t0 = clock.now()
    with clock.parallel(), clock.lane("cam0"):
        clock.sleep(0.01)
    assert clock.now() - t0 >= 0.01
