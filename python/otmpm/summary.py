"""otmpm.Summary: what a run reports (otmpm.run, Simulation.finish)."""
import collections.abc
import types


class Summary(collections.abc.Mapping):
    """What a run reports, as a read-only dict (also readable as attributes; setting or
    deleting an attribute or an item raises, errors and phases are read-only mappings).

    Keys: status ("ok", "interrupted", "unstable: <diagnosis>", "output error: <message>"
    or "out of memory: <message>"), exit_code (the command line's: 0 ok, 1 unstable,
    4 the results could not be written or memory ran out, 130 interrupted), interrupted
    (True when the run was stopped before t_end: Ctrl-C, interrupt()), mode, integrator,
    basis, steps, time (simulated time reached [s]), wall_seconds,
    particles, nodes, particle_steps_per_second, errors (dict: the errors
    against the exact solution of the scene's [reference], e.g.
    rms_velocity_error, history_error_A), max_energy_ratio, energy_drift,
    phases (dict: wall seconds per phase), diagnostics (dict, empty in mpm
    mode: node_resets in ul mode, widened_supports and moved_points with a
    searching basis in ul mode), initial_equilibrium (how the gravity-loading phase of
    simulation.initial_equilibrium ended, None without one), out_file (None without a
    result file). The values are those the result file stores as root attributes.
    str(summary) is the command line's summary line.
    """

    def __init__(self, values, line=""):
        values = dict(values)
        for key in ("errors", "phases", "diagnostics"):  # read-only views of copies: the summary never changes
            if isinstance(values.get(key), collections.abc.Mapping):
                values[key] = types.MappingProxyType(dict(values[key]))
        object.__setattr__(self, "_values", values)
        object.__setattr__(self, "_line", line)

    def __setattr__(self, name, value):
        raise AttributeError(f"Summary is read-only: cannot set '{name}'")

    def __delattr__(self, name):
        raise AttributeError(f"Summary is read-only: cannot delete '{name}'")

    def __getitem__(self, key):
        return self._values[key]

    def __iter__(self):
        return iter(self._values)

    def __len__(self):
        return len(self._values)

    def __getattr__(self, name):
        try:
            return self.__dict__["_values"][name]
        except KeyError:
            raise AttributeError(f"Summary has no key '{name}'") from None

    def __str__(self):
        return self._line

    def __repr__(self):
        keys = ("status", "steps", "time", "wall_seconds", "errors")
        return "Summary(" + ", ".join(f"{k}={self._values[k]!r}" for k in keys) + ", ...)"
