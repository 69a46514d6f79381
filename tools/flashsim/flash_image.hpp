// flash_image.hpp - the ATmega2560's 256 KiB flash kept in a file, with the bootloader in its boot section.
#pragma once

#include <cstdint>
#include <string>

extern "C" {
#include "sim_avr.h"
}

namespace rbx1::flashsim {

// The Mega 2560's fuses as Arduino ships them (boards.txt): high 0xD8 = BOOTSZ 4096 words (boot section at byte
// 0x3E000), BOOTRST programmed (reset starts there), EESAVE unprogrammed; extended 0xFD; low 0xFF.
constexpr uint32_t kBootStart = 0x3E000;
constexpr uint8_t kLowFuse = 0xFF, kHighFuse = 0xD8, kExtFuse = 0xFD, kLockBits = 0xCF;

// Maps FILE (created blank, all 0xFF, when missing) as the core's flash, so every page the bootloader writes is
// in the file at once, and writes the bootloader HEX into the boot section (on the chip the lock bits keep it
// there; here it is rewritten at each start). Sets BOOTRST's reset vector. Returns false with error set.
bool map_flash(avr_t* avr, const std::string& file, const std::string& bootloader_hex, std::string& error);

// Writes the mapped flash back to its file (on exit).
void sync_flash(avr_t* avr);

}  // namespace rbx1::flashsim
