// calibration_file.cpp - the calibration JSON file (versioned, atomically written, strictly checked on load).
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "calibration.hpp"

namespace rbx1::calib {
namespace {

using nlohmann::json;

// A failed check: the message names the field, so a user can find the broken line.
struct FieldError {
  std::string message;
};

const json& field(const json& doc, const char* key) {
  auto it = doc.find(key);
  if (it == doc.end()) throw FieldError{std::string("missing field \"") + key + "\""};
  return *it;
}

double number(const json& v, const std::string& what) {
  if (!v.is_number()) throw FieldError{what + " must be a number, got " + v.type_name()};
  const double x = v.get<double>();
  if (!std::isfinite(x)) throw FieldError{what + " is not finite"};
  return x;
}

cv::Mat matrix(const json& v, int rows, int cols, const std::string& what) {
  if (!v.is_array() || static_cast<int>(v.size()) != rows)
    throw FieldError{what + " must be an array of " + std::to_string(rows) + " rows"};
  cv::Mat m(rows, cols, CV_64F);
  for (int r = 0; r < rows; ++r) {
    const json& row = v[r];
    if (!row.is_array() || static_cast<int>(row.size()) != cols)
      throw FieldError{what + " row " + std::to_string(r) + " must be an array of " + std::to_string(cols) +
                       " numbers"};
    for (int c = 0; c < cols; ++c)
      m.at<double>(r, c) = number(row[c], what + "[" + std::to_string(r) + "][" + std::to_string(c) + "]");
  }
  return m;
}

json to_json(const cv::Mat& m) {
  json rows = json::array();
  for (int r = 0; r < m.rows; ++r) {
    json row = json::array();
    for (int c = 0; c < m.cols; ++c) row.push_back(m.at<double>(r, c));
    rows.push_back(row);
  }
  return rows;
}

cv::Point2d point(const json& v, const std::string& what) {
  if (!v.is_array() || v.size() != 2) throw FieldError{what + " must be [x, y]"};
  return {number(v[0], what + "[0]"), number(v[1], what + "[1]")};
}

bool read_json(const std::string& path, json& doc, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open: " + std::strerror(errno);
    return false;
  }
  std::stringstream text;
  text << in.rdbuf();
  doc = json::parse(text.str(), nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) {
    error = path + ": not valid JSON";
    return false;
  }
  if (!doc.is_object()) {
    error = path + ": the top level must be a JSON object";
    return false;
  }
  return true;
}

}  // namespace

bool load_calibration(const std::string& path, Calibration& out, std::string& error) {
  json doc;
  if (!read_json(path, doc, error)) return false;
  try {
    const json& format = field(doc, "format");
    if (!format.is_string() || format.get<std::string>() != "rbx1-calibration")
      throw FieldError{"\"format\" must be \"rbx1-calibration\""};
    const json& version = field(doc, "version");
    if (!version.is_number_integer()) throw FieldError{"\"version\" must be an integer"};
    if (version.get<int>() != kFileVersion)
      throw FieldError{"version " + std::to_string(version.get<int>()) + " is not supported (expected " +
                       std::to_string(kFileVersion) + ")"};
    Calibration c;
    c.homography = matrix(field(doc, "homography"), 3, 3, "\"homography\"");
    if (std::abs(cv::determinant(c.homography)) < 1e-15) throw FieldError{"\"homography\" is singular"};
    const json& k = field(doc, "camera_matrix");
    const json& d = field(doc, "dist_coeffs");
    const json& size = field(doc, "image_size");
    if (k.is_null() != d.is_null() || k.is_null() != size.is_null())
      throw FieldError{"\"camera_matrix\", \"dist_coeffs\" and \"image_size\" must be all set or all null"};
    if (!k.is_null()) {
      c.camera_matrix = matrix(k, 3, 3, "\"camera_matrix\"");
      const double fx = c.camera_matrix.at<double>(0, 0), fy = c.camera_matrix.at<double>(1, 1);
      if (!(fx > 0 && fy > 0)) throw FieldError{"\"camera_matrix\" focal lengths must be positive"};
      if (!d.is_array() || (d.size() != 4 && d.size() != 5 && d.size() != 8 && d.size() != 12 && d.size() != 14))
        throw FieldError{"\"dist_coeffs\" must be an array of 4, 5, 8, 12 or 14 numbers"};
      c.dist_coeffs = cv::Mat(1, static_cast<int>(d.size()), CV_64F);
      for (size_t i = 0; i < d.size(); ++i)
        c.dist_coeffs.at<double>(0, static_cast<int>(i)) = number(d[i], "\"dist_coeffs\"[" + std::to_string(i) + "]");
      if (!size.is_array() || size.size() != 2 || !size[0].is_number_integer() || !size[1].is_number_integer() ||
          size[0].get<int>() <= 0 || size[1].get<int>() <= 0)
        throw FieldError{"\"image_size\" must be [width, height], positive integers"};
      c.image_size = cv::Size(size[0].get<int>(), size[1].get<int>());
    }
    out = c;
    return true;
  } catch (const FieldError& e) {
    error = path + ": " + e.message;
  } catch (const nlohmann::json::exception& e) {
    error = path + ": " + e.what();
  }
  return false;
}

bool save_calibration(const std::string& path, const Calibration& c, std::string& error) {
  if (c.homography.rows != 3 || c.homography.cols != 3) {
    error = path + ": the calibration has no 3x3 homography";
    return false;
  }
  json doc;
  doc["format"] = "rbx1-calibration";
  doc["version"] = kFileVersion;
  cv::Mat h;
  c.homography.convertTo(h, CV_64F);
  doc["homography"] = to_json(h);
  if (c.has_intrinsics()) {
    cv::Mat k, d;
    c.camera_matrix.convertTo(k, CV_64F);
    c.dist_coeffs.convertTo(d, CV_64F);
    doc["camera_matrix"] = to_json(k);
    d = d.reshape(1, 1);
    doc["dist_coeffs"] = to_json(d)[0];
    doc["image_size"] = {c.image_size.width, c.image_size.height};
  } else {
    doc["camera_matrix"] = nullptr;
    doc["dist_coeffs"] = nullptr;
    doc["image_size"] = nullptr;
  }
  const std::string text = doc.dump(2) + "\n";
  // Write a temporary file beside the target, flush it to disk, then rename: readers see old or new, never half.
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = path + ": cannot write: " + std::strerror(errno);
    return false;
  }
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      error = path + ": write failed: " + std::strerror(errno);
      ::close(fd);
      ::unlink(tmp.c_str());
      return false;
    }
    done += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    error = path + ": cannot flush: " + std::strerror(errno);
    ::unlink(tmp.c_str());
    return false;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": cannot replace: " + std::strerror(errno);
    ::unlink(tmp.c_str());
    return false;
  }
  return true;
}

bool load_table_points(const std::string& path, std::vector<TablePoint>& out, std::string& error) {
  json doc;
  if (!read_json(path, doc, error)) return false;
  try {
    const json& pts = field(doc, "points");
    if (!pts.is_array()) throw FieldError{"\"points\" must be an array"};
    std::vector<TablePoint> list;
    for (size_t i = 0; i < pts.size(); ++i) {
      const std::string what = "points[" + std::to_string(i) + "]";
      if (!pts[i].is_object()) throw FieldError{what + " must be an object {\"px\": [x, y], \"cm\": [x, y]}"};
      list.push_back({point(field(pts[i], "px"), what + ".px"), point(field(pts[i], "cm"), what + ".cm")});
    }
    out = std::move(list);
    return true;
  } catch (const FieldError& e) {
    error = path + ": " + e.message;
  }
  return false;
}

}  // namespace rbx1::calib
