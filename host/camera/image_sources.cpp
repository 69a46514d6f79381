// image_sources.cpp - frames from an image file or a folder of images, the [camera] table, and open_source().
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <sys/stat.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include "frame_source.hpp"
#include "socket_source.hpp"
#include "v4l2_capture.hpp"

namespace rbx1::camera {

namespace fs = std::filesystem;

namespace {

bool is_image_name(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const char* e : {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".pnm", ".webp"})
    if (ext == e) return true;
  return false;
}

// Reads one image as BGR; 0, or -errno with error "PATH: reason".
int load_image(const std::string& path, cv::Mat& out, std::string& error) {
  if (access(path.c_str(), R_OK) != 0) {
    int e = errno;
    error = path + ": " + std::strerror(e);
    return -e;
  }
  out = cv::imread(path, cv::IMREAD_COLOR);
  if (out.empty()) {
    error = path + ": not a readable image (corrupt or unsupported format)";
    return -EBADMSG;
  }
  return 0;
}

class ImageFileSource : public FrameSource {
 public:
  ImageFileSource(std::string path, cv::Mat image) : path_(std::move(path)), image_(std::move(image)) {}
  int read(cv::Mat& bgr) override {
    image_.copyTo(bgr);  // the caller may draw on it
    return 0;
  }
  std::string describe() const override {
    return "image " + path_ + " (" + std::to_string(image_.cols) + "x" + std::to_string(image_.rows) + ")";
  }

 private:
  std::string path_;
  cv::Mat image_;
};

class FolderSource : public FrameSource {
 public:
  FolderSource(std::string dir, std::vector<std::string> files) : dir_(std::move(dir)), files_(std::move(files)) {}
  int read(cv::Mat& bgr) override {
    const std::string& file = files_[next_];
    next_ = (next_ + 1) % files_.size();
    std::string error;
    int r = load_image(file, bgr, error);
    if (r < 0) spdlog::error("{}", error);
    return r;
  }
  std::string describe() const override {
    return "folder " + dir_ + " (" + std::to_string(files_.size()) + " images, next " +
           fs::path(files_[next_]).filename().string() + ")";
  }

 private:
  std::string dir_;
  std::vector<std::string> files_;
  size_t next_ = 0;
};

}  // namespace

void parse_camera_config(rbx1::config::Section camera, CameraConfig& out) {
  out.device = camera.string("device", out.device);
  out.width = static_cast<int>(camera.integer("width", out.width, 16, 7680));
  out.height = static_cast<int>(camera.integer("height", out.height, 16, 4320));
  out.fps = static_cast<int>(camera.integer("fps", out.fps, 1, 240));
  std::string format = camera.string("format", out.format);
  if (format == "YUYV" || format == "MJPEG")
    out.format = format;
  else
    camera.errors().add(camera.path() + ".format", "must be \"YUYV\" or \"MJPEG\", got \"" + format + "\"");
  if (out.width % 2) camera.errors().add(camera.path() + ".width", "must be even (YUYV pairs pixels)");
  camera.reject_unknown();
}

std::unique_ptr<FrameSource> open_source(const CameraConfig& config, std::string& error) {
  const std::string& path = config.device;
  if (path.empty()) {
    error = "camera.device: not set (a /dev/video device, an image file, a folder or unix:SOCKET)";
    return nullptr;
  }
  if (path.rfind(kSocketPrefix, 0) == 0) {
    auto source = std::make_unique<SocketSource>(path.substr(std::strlen(kSocketPrefix)));
    if (source->open(error) < 0) return nullptr;
    return source;
  }
  struct stat st{};
  bool exists = ::stat(path.c_str(), &st) == 0;
  if (S_ISCHR(st.st_mode) || (!exists && path.rfind("/dev/video", 0) == 0)) {
    auto cap = std::make_unique<V4L2Capture>();
    if (cap->open(config, error) < 0) return nullptr;
    return cap;
  }
  if (exists && S_ISDIR(st.st_mode)) {
    std::vector<std::string> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(path, ec))
      if (e.is_regular_file() && is_image_name(e.path())) files.push_back(e.path().string());
    if (ec) {
      error = path + ": " + ec.message();
      return nullptr;
    }
    if (files.empty()) {
      error = path + ": no images in the folder (png, jpg, bmp, tif, pnm, webp)";
      return nullptr;
    }
    std::sort(files.begin(), files.end());
    return std::make_unique<FolderSource>(path, std::move(files));
  }
  cv::Mat image;
  if (load_image(path, image, error) < 0) return nullptr;
  return std::make_unique<ImageFileSource>(path, std::move(image));
}

}  // namespace rbx1::camera
