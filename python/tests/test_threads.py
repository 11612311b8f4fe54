"""Objects shared by threads: each TemporalMap and Integrator serialises the calls on it, so
threads that add to one object while others read it get what calling one after another gives.

Each test runs in a child interpreter: before the lock, four threads adding to one TemporalMap
ended the interpreter with a double free, and two threads sharing an Integrator aborted it.
"""

import child


def test_threads_adding_to_and_reading_one_temporal_map():
    process = child.run("""
        import threading
        import numpy as np
        import chronomap
        import scenes

        sessions = [scenes.session(with_box=False), scenes.session(with_box=True)]
        THREADS, EACH = 4, 12
        shared = chronomap.TemporalMap(scenes.RESOLUTION_M)
        errors, done = [], threading.Event()

        def adder(k):
            try:
                for i in range(EACH):
                    n = i * THREADS + k
                    shared.add(sessions[n % 2], 1000.0 * n)
            except BaseException as e:
                errors.append(repr(e))

        def reader():
            try:
                while not done.is_set():
                    sizes = (len(shared), shared.times_s.size)
                    shared.snapshot(1e6)
                    shared.change_histogram()
                    shared.history(np.array([0.0, 0.0, 1.52]))
                    assert sizes[0] <= sizes[1] <= THREADS * EACH, sizes
            except BaseException as e:
                errors.append(repr(e))

        adders = [threading.Thread(target=adder, args=(k,)) for k in range(THREADS)]
        readers = [threading.Thread(target=reader) for _ in range(2)]
        for t in adders + readers:
            t.start()
        for t in adders:
            t.join()
        done.set()
        for t in readers:
            t.join()
        assert not errors, errors

        # The same sessions added one after another in time order give the same map.
        alone = chronomap.TemporalMap(scenes.RESOLUTION_M)
        for n in range(THREADS * EACH):
            alone.add(sessions[n % 2], 1000.0 * n)
        assert np.array_equal(shared.times_s, alone.times_s)
        for t in alone.times_s:
            assert shared.snapshot(t) == alone.snapshot(t), t
        assert np.array_equal(shared.change_histogram(), alone.change_histogram())
        assert shared.history(np.array([0.0, 0.0, 1.52])) == alone.history(np.array([0.0, 0.0, 1.52]))
        print("sessions", len(shared))
    """)
    assert process.returncode == 0, child.describe(process)
    assert "sessions 48" in process.stdout


def test_an_integrator_shared_by_threads():
    process = child.run("""
        import threading
        import numpy as np
        import chronomap
        import scenes

        points = scenes.wall()
        THREADS, EACH = 4, 8
        shared = chronomap.Integrator(resolution_m=scenes.RESOLUTION_M, max_range_m=5.0)
        errors, done = [], threading.Event()

        def adder():
            try:
                for _ in range(EACH):
                    shared.add_points(points, np.zeros(3))
            except BaseException as e:
                errors.append(repr(e))

        def reader():
            try:
                seen = 0
                while not done.is_set():
                    frames = shared.frames
                    assert frames >= seen, (frames, seen)
                    seen = frames
                    shared.map
            except BaseException as e:
                errors.append(repr(e))

        adders = [threading.Thread(target=adder) for _ in range(THREADS)]
        readers = [threading.Thread(target=reader) for _ in range(2)]
        for t in adders + readers:
            t.start()
        for t in adders:
            t.join()
        done.set()
        for t in readers:
            t.join()
        assert not errors, errors
        assert shared.frames == THREADS * EACH and shared.points == THREADS * EACH * len(points)

        # Every thread added the same frame: any order is the order of one thread adding them all.
        alone = chronomap.Integrator(resolution_m=scenes.RESOLUTION_M, max_range_m=5.0)
        for _ in range(THREADS * EACH):
            alone.add_points(points, np.zeros(3))
        assert shared.finish() == alone.finish()
        print("frames", THREADS * EACH)
    """)
    assert process.returncode == 0, child.describe(process)
    assert "frames 32" in process.stdout
