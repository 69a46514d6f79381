// clock_file.cpp - the mapped clock file of a simulated board (see clock_file.hpp).
#include "clock_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace rbx1::simpty {

volatile uint8_t* map_clock_file(const std::string& path, std::string& error) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC, 0644);
  void* m = fd >= 0 && ftruncate(fd, 16) == 0 ? mmap(nullptr, 16, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0)
                                              : MAP_FAILED;
  const int saved = errno;
  if (fd >= 0) ::close(fd);
  if (m == MAP_FAILED) {
    error = path + ": " + std::strerror(saved);
    return nullptr;
  }
  return static_cast<volatile uint8_t*>(m);
}

}  // namespace rbx1::simpty
