// atomic_file.hpp - whole-file writes that readers see old or new, never half: temp file, fsync, rename, fsync dir.
#pragma once
#include <string>

namespace rbx1 {

// Writes bytes to PATH.tmp.<pid> beside path, fsyncs it, renames it over path and fsyncs the folder.
// false + error "PATH: reason" (the old file, if any, is left as it was).
bool write_file_atomic(const std::string& path, const std::string& bytes, std::string& error);

}  // namespace rbx1
