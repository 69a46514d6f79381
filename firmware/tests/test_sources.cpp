// test_sources.cpp - the core's folder is safe on a host include path: no header there shares its name with a
// system header (a firmware "limits.h" once hid <limits.h> and broke <atomic> for rbx1-avrsim).
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "fw_fixture.hpp"

namespace rbx1::fwtest {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> split(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, ':');)
    if (!item.empty()) out.push_back(item);
  return out;
}

// Headers of dir that a system include directory also has: `#include <name>` would find the wrong one.
std::vector<std::string> shadowing(const fs::path& dir, const std::vector<std::string>& system_dirs) {
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::string name = e.path().filename().string();
    if (e.path().extension() != ".h" && e.path().extension() != ".hpp") continue;
    for (const auto& sys : system_dirs) {
      if (fs::exists(fs::path(sys) / name)) {
        found.push_back(name + " (also " + sys + "/" + name + ")");
        break;  // once per header
      }
    }
  }
  return found;
}

TEST_F(Fw, NoCoreHeaderShadowsASystemHeader) {
  std::vector<std::string> system_dirs = split(RBX1_SYSTEM_INCLUDE_DIRS);
  ASSERT_FALSE(system_dirs.empty());
  // The check itself can fail: a scratch folder with a limits.h is caught.
  fs::path scratch = fs::temp_directory_path() / ("rbx1fw-shadow-" + std::to_string(::getpid()));
  fs::create_directories(scratch);
  std::ofstream(scratch / "limits.h") << "// shadow\n";
  std::ofstream(scratch / "stepper.h") << "// fine\n";
  std::vector<std::string> caught = shadowing(scratch, system_dirs);
  fs::remove_all(scratch);
  ASSERT_EQ(caught.size(), 1u);
  EXPECT_EQ(caught[0].rfind("limits.h", 0), 0u);
  // The real folder: nothing.
  std::vector<std::string> found = shadowing(RBX1FW_SRC_DIR, system_dirs);
  std::string all;
  for (const auto& f : found) all += f + "; ";
  EXPECT_TRUE(found.empty()) << "rename (module prefix convention): " << all;
}

}  // namespace
}  // namespace rbx1::fwtest
