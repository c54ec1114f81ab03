#pragma once
// STEP/IGES import in a child process (private to io).
//
// Why a child process. OpenCASCADE's STEP reader recurses through the entity graph without a
// depth limit: an entity that references itself (directly, or through another) overflows the
// stack inside OCCT (fuzz findings step_*_self_ref_stack_overflow.step). A stack overflow cannot
// be caught in-process -- OCC_CATCH_SIGNALS turns ordinary SIGSEGVs into exceptions, but the
// handler itself has no stack left to run on -- and a reader that loops or allocates without
// bound cannot be interrupted safely either. A pre-pass rejecting reference cycles in the STEP
// entity graph would cover this one pattern of one format only (not IGES, not other OCCT bugs,
// not hangs), and legal STEP files may hold cycles OCCT never follows. So the import runs in a
// forked child with limits on its address space (RLIMIT_AS), CPU time (RLIMIT_CPU) and
// wall-clock time (the parent kills it), and hands the converted model back through a pipe as
// the project's JSON model (model_to_json / parse_model: exact, bit for bit) plus the import
// report; a crash, a limit or a hang becomes InputError, one line naming the file.
//
// Fork, not exec: the child needs no binary of its own to be found and installed, and inherits
// the parent's state for free. The parent holds the OCCT lock across fork(), so no other thread
// of it is inside OCCT at that instant; the child then uses only OCCT, malloc (fork-safe in
// glibc) and its inherited stderr. Cost: measured in README "Resource limits" (the JSON
// transport is a few percent of an import, which OCCT's own conversion dominates).
//
// Limits: resource_limits() (NURBSREG_CAD_TIMEOUT, NURBSREG_CAD_MEMORY_MB). Under
// AddressSanitizer, ThreadSanitizer or MemorySanitizer the address-space limit is not set (their
// shadow memory reserves terabytes of address space).

#include <mutex>
#include <string>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/io/cad_import.hpp"

namespace nurbsreg::io::cad_detail {

// The import itself, in this process, by the OpenCASCADE module (occt_module.hpp; OCCT's
// exceptions and ordinary crash signals become InputError; a stack overflow still kills the
// process). Serialised by occt_mutex() unless take_lock is false (the child process, whose
// parent holds it).
engine::Model import_in_process(const std::string& path, CadImportReport* report,
                                bool take_lock = true);

// import_in_process in a child process, as described above; the model comes back through
// parse_model, so it passes the same load-time checks as a JSON file.
engine::Model import_isolated(const std::string& path, CadImportReport* report);

// The lock that serialises OCCT's data-exchange sessions (global state) in this process.
std::mutex& occt_mutex();

}  // namespace nurbsreg::io::cad_detail
