#pragma once
// Writes a file atomically: the content goes to a temporary name in the same directory, which is
// renamed over the target only once it is complete and flushed. Readers never see a partial
// file, and an interrupted run leaves no output (at most a `.<name>.tmp-*` file that is removed
// on the next failure path or ignored by readers).

#include <functional>
#include <ostream>
#include <string>

namespace nurbsreg::io {

// Calls `write` with a binary stream; on success renames into place, on any exception removes
// the temporary and rethrows. Throws OutputError when the file cannot be created or renamed.
void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& write);

}  // namespace nurbsreg::io
