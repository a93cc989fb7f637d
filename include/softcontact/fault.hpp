#pragma once
// Deterministic fault injection, a testing hook (docs/reliability.md, "Fault injection").
//
// SOFTCONTACT_FAULT=ACTION:POINT:STEP[:RANK] makes the run fail on purpose the first time
// POINT is reached at or after step STEP, on rank RANK of MPI_COMM_WORLD (default: all):
//
//   ACTION   kill      raise SIGKILL on itself (what `kill -9` does)
//            sigterm   raise SIGTERM on itself (what a batch scheduler sends)
//            sigint    raise SIGINT on itself (Ctrl-C)
//            ioerror   the write fails as an I/O error would (POINT: a write or rename)
//            nan       a vertex position becomes non-finite (POINT: step)
//   POINT    step                after the step is computed, before the guard's check
//            frame_write         half-way through a frame file (positions written, the rest not)
//            frame_rename        the frame file complete under *.tmp, before its rename
//            frame_renamed       after the rename, before the index and the XDMF name it
//            checkpoint_write    half-way through a checkpoint (positions written)
//            checkpoint_rename   the checkpoint complete under *.tmp, before flush and rename
//            checkpoint_renamed  after the rename, before older checkpoints are pruned
//
// The variable is read once, by configure(); unset, every injection point costs one test
// of a boolean. A bad value is an InputError (exit status 2).
#include <cstdint>
#include <string>

namespace softcontact::fault {

enum class Point { step, frame_write, frame_rename, frame_renamed, checkpoint_write, checkpoint_rename, checkpoint_renamed };

/// Reads SOFTCONTACT_FAULT (`value` in tests) for this process, rank `rank` of `size`.
/// Throws InputError naming the variable and what was expected when it is malformed.
void configure(int rank, int size);
void configure(const char* value, int rank, int size);

namespace detail {
extern bool armed;
bool hit(Point p, std::int64_t step);
}  // namespace detail

/// An injection point, reached at `step`. When the configured fault fires here, `kill`,
/// `sigterm` and `sigint` act before this returns (kill never returns); it returns true
/// when the caller must inject its own failure: an I/O error at a write or rename point,
/// a non-finite position at Point::step. Fires at most once per process.
inline bool hit(Point p, std::int64_t step) { return detail::armed && detail::hit(p, step); }

/// "frame_write" etc., for messages.
const char* name(Point p);

/// The text of an injected I/O error at `p`, about `file`.
std::string io_error(Point p, const std::string& file);

}  // namespace softcontact::fault
