#pragma once
/// \file openmp_wait.hpp
/// How the OpenMP threads of otmpm's programs wait between parallel loops
/// (docs/user-guide.md, "Threads"). GNU OpenMP lets a waiting thread spin
/// GOMP_SPINCOUNT times (a relaxed atomic load and the processor's pause
/// hint per spin) before it sleeps: 300 000 spins by default, 0 with
/// OMP_WAIT_POLICY=passive. Spinning that long makes a run on a busy machine
/// many times slower (a spinning thread holds the core its partner needs);
/// not spinning at all makes every parallel loop of an idle machine pay a
/// wake-up. otmpm's default is in between: passive, with a spin of about
/// kDefaultSpinSeconds, counted for the processor it runs on (a pause takes
/// from a few to about 50 ns, depending on the processor).

#include <vector>

namespace otmpm {

/// Seconds a waiting OpenMP thread spins before it sleeps, by default
/// (measured: docs/performance-log-2026.md, "How OpenMP threads wait").
inline constexpr double kDefaultSpinSeconds = 2e-4;

/// The GOMP_SPINCOUNT that spins for about `seconds` on this processor: the
/// shortest of three timings of 2 048 spins of libgomp's wait loop (about 50
/// us each; 50 ns per spin when the clock does not see them), clamped to
/// [100, 10^7].
long long spin_count_for(double seconds);

/// The CPUs of every OpenMP place, ascending: where OMP_PROC_BIND,
/// OMP_PLACES or GOMP_CPU_AFFINITY bind the threads, the CPUs the process was
/// started with (for a list of places, the listed ones among them); empty
/// where the threads are not bound (or without OpenMP). libgomp binds each
/// process's first thread to the first place, so processes started side
/// by side must each be given their own share of these (the study does).
std::vector<int> openmp_place_cpus();

/// Lets the calling thread run on the CPUs of every OpenMP place (nothing
/// where the threads are not bound). libgomp binds a program's first thread
/// to the first place when it is loaded: a process that thread starts again
/// would inherit that one place as all its CPUs (default_openmp_wait), and a
/// thread it starts outside OpenMP (the result file's writer) would share
/// that place's core with the first OpenMP thread.
void allow_every_place();

/// True when the program runs under valgrind (its core library is preloaded:
/// LD_PRELOAD names vgpreload_*). There /proc/self/exe is valgrind's tool,
/// which cannot be executed again on its own.
bool under_valgrind();

/// When neither OMP_WAIT_POLICY nor GOMP_SPINCOUNT is set, sets
/// OMP_WAIT_POLICY=passive and GOMP_SPINCOUNT=spin_count_for(
/// kDefaultSpinSeconds) and executes the program again with the same
/// arguments (libgomp reads both once, when it is loaded), with the CPUs of
/// every OpenMP place (where a user's OMP_PROC_BIND bound this process to
/// the first place, the new one would otherwise run every thread there). A
/// user's own setting of either is kept. Nothing without OpenMP or under valgrind
/// (under_valgrind: libgomp's defaults, or the caller's settings); when the
/// new process cannot be started, the program goes on with libgomp's
/// defaults. Call it first in main, before any thread or MPI starts.
void default_openmp_wait(char** argv);

} // namespace otmpm
