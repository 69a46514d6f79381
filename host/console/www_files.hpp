// www_files.hpp - the console's static page, compiled into rbx1d from www/ (embed_www.cmake writes the table).
#pragma once
#include <cstddef>

namespace rbx1::console {

struct WwwFile {
  const char* path;  // URL path, e.g. "/index.html"
  const char* type;  // Content-Type
  const unsigned char* data;
  size_t size;
};

extern const WwwFile kWwwFiles[];
extern const size_t kWwwFileCount;

}  // namespace rbx1::console
