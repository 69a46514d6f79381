// flash_image.cpp - the flash file mapped as the core's flash, and the bootloader HEX loaded into the boot section.
#include "flash_image.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

extern "C" {
#include "sim_hex.h"
}

namespace rbx1::flashsim {

bool map_flash(avr_t* avr, const std::string& file, const std::string& bootloader_hex, std::string& error) {
  const size_t size = avr->flashend + 1;
  ihex_chunk_p chunks = nullptr;
  const int count = access(bootloader_hex.c_str(), R_OK) == 0 ? read_ihex_chunks(bootloader_hex.c_str(), &chunks) : -1;
  if (count <= 0) {
    error = bootloader_hex + ": cannot read the bootloader HEX";
    return false;
  }
  for (int i = 0; i < count; i++) {
    if (chunks[i].baseaddr < kBootStart || chunks[i].baseaddr + chunks[i].size > size) {
      error = bootloader_hex + ": not a boot-section image (data at 0x" + std::to_string(chunks[i].baseaddr) + ")";
      free_ihex_chunks(chunks);
      return false;
    }
  }
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT, 0644);
  struct stat st {};
  if (fd < 0 || fstat(fd, &st) != 0) {
    error = file + ": " + std::strerror(errno);
    free_ihex_chunks(chunks);
    return false;
  }
  const bool blank = static_cast<size_t>(st.st_size) != size;
  if (blank && ftruncate(fd, static_cast<off_t>(size)) != 0) {
    error = file + ": " + std::strerror(errno);
    close(fd);
    free_ihex_chunks(chunks);
    return false;
  }
  void* map = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  close(fd);
  if (map == MAP_FAILED) {
    error = file + ": mmap: " + std::strerror(errno);
    free_ihex_chunks(chunks);
    return false;
  }
  auto* flash = static_cast<uint8_t*>(map);
  if (blank) std::memset(flash, 0xFF, size);  // an erased chip: a file of another size is a new, blank board
  for (int i = 0; i < count; i++) std::memcpy(flash + chunks[i].baseaddr, chunks[i].data, chunks[i].size);
  free_ihex_chunks(chunks);
  std::free(avr->flash);
  avr->flash = flash;
  avr->codeend = avr->flashend;  // the application may end anywhere below the boot section
  avr->fuse[AVR_FUSE_LOW] = kLowFuse;
  avr->fuse[AVR_FUSE_HIGH] = kHighFuse;
  avr->fuse[AVR_FUSE_EXT] = kExtFuse;
  avr->lockbits = kLockBits;
  avr->reset_pc = kBootStart;  // BOOTRST
  avr->pc = kBootStart;
  return true;
}

void sync_flash(avr_t* avr) { msync(avr->flash, avr->flashend + 1, MS_SYNC); }

}  // namespace rbx1::flashsim
