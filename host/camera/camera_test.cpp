// camera_test.cpp - file and folder sources, YUYV/MJPEG conversion on synthetic buffers, the [camera] table,
// clear errors, and a real V4L2 device when one exists.
#include <filesystem>
#include <fstream>
#include <pty.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include "convert.hpp"
#include "frame_source.hpp"

using namespace rbx1::camera;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("rbx1-camera-" + std::to_string(getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  std::string file(const std::string& name) const { return (path / name).string(); }
};

cv::Mat solid(int w, int h, cv::Scalar bgr) { return cv::Mat(h, w, CV_8UC3, bgr); }

// A YUYV buffer filled with one colour.
std::vector<uint8_t> yuyv_fill(int w, int h, uint8_t y, uint8_t u, uint8_t v, size_t stride = 0) {
  if (!stride) stride = size_t(w) * 2;
  std::vector<uint8_t> buf(stride * h, 0xEE);
  for (int r = 0; r < h; ++r)
    for (int x = 0; x < w; x += 2) {
      uint8_t* p = &buf[r * stride + x * 2];
      p[0] = y, p[1] = u, p[2] = y, p[3] = v;
    }
  return buf;
}

}  // namespace

TEST(Convert, YuyvGrayAndRed) {
  cv::Mat bgr;
  auto gray = yuyv_fill(64, 48, 200, 128, 128);
  ASSERT_EQ(yuyv_to_bgr(gray.data(), gray.size(), 64, 48, 0, bgr), 0);
  ASSERT_EQ(bgr.type(), CV_8UC3);
  ASSERT_EQ(bgr.size(), cv::Size(64, 48));
  // Cameras send BT.601 video range (Y 16..235): gray Y=200 is 1.164 * (200 - 16) = 214.
  cv::Vec3b p = bgr.at<cv::Vec3b>(20, 31);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(p[c], 214, 1);
  // Pure red in BT.601 video range: Y=81, U=90, V=240.
  auto red = yuyv_fill(64, 48, 81, 90, 240);
  ASSERT_EQ(yuyv_to_bgr(red.data(), red.size(), 64, 48, 0, bgr), 0);
  p = bgr.at<cv::Vec3b>(47, 63);
  EXPECT_LT(p[0], 10);
  EXPECT_LT(p[1], 10);
  EXPECT_GT(p[2], 245);
}

TEST(Convert, YuyvHonoursTheStrideAndRejectsShortBuffers) {
  cv::Mat bgr;
  auto padded = yuyv_fill(32, 8, 100, 128, 128, 96);  // 32 padding bytes per line (filled with 0xEE)
  ASSERT_EQ(yuyv_to_bgr(padded.data(), padded.size(), 32, 8, 96, bgr), 0);
  EXPECT_NEAR(bgr.at<cv::Vec3b>(7, 31)[1], 98, 1);  // 1.164 * (100 - 16)
  EXPECT_EQ(yuyv_to_bgr(padded.data(), padded.size() - 100, 32, 8, 96, bgr), -EINVAL);
  EXPECT_EQ(yuyv_to_bgr(padded.data(), padded.size(), 31, 8, 0, bgr), -EINVAL);  // odd width
}

TEST(Convert, MjpegDecodesAndRejectsGarbage) {
  cv::Mat src = solid(80, 60, {30, 160, 220});
  cv::rectangle(src, {10, 10}, {40, 40}, {0, 0, 0}, cv::FILLED);
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", src, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  cv::Mat bgr;
  ASSERT_EQ(mjpeg_to_bgr(jpeg.data(), jpeg.size(), bgr), 0);
  ASSERT_EQ(bgr.size(), src.size());
  cv::Vec3b a = bgr.at<cv::Vec3b>(50, 70), b = bgr.at<cv::Vec3b>(25, 25);
  EXPECT_NEAR(a[0], 30, 6);
  EXPECT_NEAR(a[1], 160, 6);
  EXPECT_NEAR(a[2], 220, 6);
  EXPECT_LT(b[0] + b[1] + b[2], 20);
  std::vector<uint8_t> junk(500, 0x42);
  EXPECT_EQ(mjpeg_to_bgr(junk.data(), junk.size(), bgr), -EBADMSG);
  EXPECT_EQ(mjpeg_to_bgr(nullptr, 0, bgr), -EBADMSG);
}

TEST(FileSource, ReturnsTheImageOnEveryRead) {
  TempDir dir;
  std::string file = dir.file("scene.png");
  ASSERT_TRUE(cv::imwrite(file, solid(40, 30, {10, 20, 30})));
  std::string error;
  auto src = open_source(CameraConfig{file}, error);
  ASSERT_NE(src, nullptr) << error;
  for (int i = 0; i < 3; ++i) {
    cv::Mat frame;
    ASSERT_EQ(src->read(frame), 0);
    ASSERT_EQ(frame.size(), cv::Size(40, 30));
    EXPECT_EQ(frame.at<cv::Vec3b>(5, 5), cv::Vec3b(10, 20, 30));
    frame.setTo(cv::Scalar(0, 0, 0));  // the caller's copy, not the source's
  }
  EXPECT_NE(src->describe().find("40x30"), std::string::npos);
}

TEST(FileSource, ClearErrorsNameThePath) {
  TempDir dir;
  std::string error;
  EXPECT_EQ(open_source(CameraConfig{dir.file("missing.png")}, error), nullptr);
  EXPECT_EQ(error, dir.file("missing.png") + ": No such file or directory");
  std::ofstream(dir.file("corrupt.png")) << "\x89PNG\r\n\x1a\nthis is not really a png";
  EXPECT_EQ(open_source(CameraConfig{dir.file("corrupt.png")}, error), nullptr);
  EXPECT_EQ(error, dir.file("corrupt.png") + ": not a readable image (corrupt or unsupported format)");
  EXPECT_EQ(open_source(CameraConfig{""}, error), nullptr);
  EXPECT_EQ(error.rfind("camera.device: not set", 0), 0u);
}

TEST(FolderSource, ImagesInNameOrderCycling) {
  TempDir dir;
  ASSERT_TRUE(cv::imwrite(dir.file("b.png"), solid(8, 8, {0, 2, 0})));
  ASSERT_TRUE(cv::imwrite(dir.file("a.png"), solid(8, 8, {0, 1, 0})));
  ASSERT_TRUE(cv::imwrite(dir.file("c.bmp"), solid(8, 8, {0, 3, 0})));
  std::ofstream(dir.file("notes.txt")) << "not an image";
  std::string error;
  auto src = open_source(CameraConfig{dir.path.string()}, error);
  ASSERT_NE(src, nullptr) << error;
  std::vector<int> seen;
  for (int i = 0; i < 7; ++i) {
    cv::Mat f;
    ASSERT_EQ(src->read(f), 0);
    seen.push_back(f.at<cv::Vec3b>(0, 0)[1]);
  }
  EXPECT_EQ(seen, (std::vector<int>{1, 2, 3, 1, 2, 3, 1}));
  EXPECT_NE(src->describe().find("3 images"), std::string::npos) << src->describe();
}

TEST(FolderSource, EmptyFolderAndCorruptMember) {
  TempDir dir;
  std::string error;
  EXPECT_EQ(open_source(CameraConfig{dir.path.string()}, error), nullptr);
  EXPECT_EQ(error, dir.path.string() + ": no images in the folder (png, jpg, bmp, tif, pnm, webp)");
  ASSERT_TRUE(cv::imwrite(dir.file("1.png"), solid(8, 8, {0, 0, 9})));
  std::ofstream(dir.file("2.jpg")) << "garbage";
  auto src = open_source(CameraConfig{dir.path.string()}, error);
  ASSERT_NE(src, nullptr) << error;
  cv::Mat f;
  EXPECT_EQ(src->read(f), 0);
  EXPECT_EQ(src->read(f), -EBADMSG);  // the corrupt one is reported, not skipped silently
  EXPECT_EQ(src->read(f), 0);         // and the cycle goes on
  EXPECT_EQ(f.at<cv::Vec3b>(0, 0)[2], 9);
}

TEST(V4L2, MissingOrWrongDeviceIsAClearError) {
  std::string error;
  EXPECT_EQ(open_source(CameraConfig{"/dev/video97"}, error), nullptr);
  EXPECT_EQ(error, "/dev/video97: No such file or directory");
  int master, slave;  // a character device that is not a camera: a pty
  char name[128];
  ASSERT_EQ(openpty(&master, &slave, name, nullptr, nullptr), 0);
  EXPECT_EQ(open_source(CameraConfig{name}, error), nullptr);
  EXPECT_EQ(error.rfind(std::string(name) + ": not a V4L2 device", 0), 0u) << error;
  ::close(slave);
  ::close(master);
}

TEST(V4L2, RealDeviceWhenPresent) {
  std::string device;
  for (int i = 0; i < 64 && device.empty(); ++i)
    if (access(("/dev/video" + std::to_string(i)).c_str(), F_OK) == 0) device = "/dev/video" + std::to_string(i);
  if (device.empty()) GTEST_SKIP() << "no /dev/video* on this machine: real-camera test skipped";
  int opened = 0;
  for (const char* format : {"YUYV", "MJPEG"}) {
    CameraConfig c{device, 640, 480, 30, format};
    std::string error;
    auto src = open_source(c, error);
    if (!src) {
      std::printf("%s: %s\n", format, error.c_str());  // a camera may offer only one of the two
      continue;
    }
    ++opened;
    cv::Mat f;
    int r = 0;
    for (int i = 0; i < 5; ++i) r = src->read(f);  // the first frames of some cameras are dark or partial
    ASSERT_EQ(r, 0) << src->describe();
    EXPECT_EQ(f.type(), CV_8UC3);
    EXPECT_GT(f.cols, 0);
  }
  EXPECT_GT(opened, 0) << device << ": neither YUYV nor MJPEG could be opened";
}

TEST(CameraConfig, ParsesAndChecks) {
  rbx1::config::Errors errors;
  toml::table t = rbx1::config::parse_text(
      "[camera]\ndevice = \"/dev/video2\"\nwidth = 640\nheight = 480\nfps = 15\nformat = \"MJPEG\"\n", errors);
  rbx1::config::Section root(&t, "", errors);
  CameraConfig c;
  parse_camera_config(root.section("camera"), c);
  EXPECT_TRUE(errors.ok()) << errors.joined();
  EXPECT_EQ(c.device, "/dev/video2");
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
  EXPECT_EQ(c.fps, 15);
  EXPECT_EQ(c.format, "MJPEG");

  rbx1::config::Errors bad;
  toml::table u = rbx1::config::parse_text("[camera]\nformat = \"H264\"\nfps = 0\nexposure = 3\n", bad);
  rbx1::config::Section r2(&u, "", bad);
  CameraConfig d;
  parse_camera_config(r2.section("camera"), d);
  ASSERT_EQ(bad.messages().size(), 3u) << bad.joined();
  EXPECT_EQ(bad.messages()[0].rfind("camera.fps: must be within [1, 240]", 0), 0u);
  EXPECT_EQ(bad.messages()[1], "camera.format: must be \"YUYV\" or \"MJPEG\", got \"H264\"");
  EXPECT_EQ(bad.messages()[2], "camera.exposure: unknown key");
  EXPECT_EQ(d.format, "YUYV");
  EXPECT_EQ(d.width, 1280);
}
