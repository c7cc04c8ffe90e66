"""Seconds spent in each stage of a bake, for the bake statistics (the Last Bake panel, scripts).

    times = StageTimes()
    with times("meshes"):
        ...
        with times("materials"):   # nested: its seconds are not counted in "meshes" too
            ...

Stages are exclusive: a stage entered inside another pauses the outer one, so the stages of one
timer add up to the time spent in all of them. Wall-clock seconds (.seconds) and the CPU seconds
of the calling thread (.cpu: on a busy machine, the part that does not wait for a core; work that
Blender or the engine hands to other threads is not in it). The thread's clock, not the process's:
the process's sums over all of Blender's threads and takes milliseconds a call.
"""
import contextlib
import time


class StageTimes:
    def __init__(self):
        self.seconds = {}
        self.cpu = {}
        self._stack = []   # [name, (wall, cpu) at the start of its running part]

    def _credit(self, name, now, since):
        self.seconds[name] = self.seconds.get(name, 0.0) + (now[0] - since[0])
        self.cpu[name] = self.cpu.get(name, 0.0) + (now[1] - since[1])

    @contextlib.contextmanager
    def __call__(self, name):
        now = (time.perf_counter(), time.thread_time())
        if self._stack:
            outer = self._stack[-1]
            self._credit(outer[0], now, outer[1])
        self._stack.append([name, now])
        try:
            yield
        finally:
            _, since = self._stack.pop()
            now = (time.perf_counter(), time.thread_time())
            self._credit(name, now, since)
            if self._stack:
                self._stack[-1][1] = now

    def total(self):
        return sum(self.seconds.values())
