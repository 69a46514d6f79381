// markers.cpp - ArUco marker sheets (PNG with pHYs, vector PDF) at true scale, and marker detection.
#include "markers.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "atomic_file.hpp"

namespace rbx1::calib {

namespace {

const std::map<std::string, cv::aruco::PREDEFINED_DICTIONARY_NAME>& dictionaries() {
  using namespace cv::aruco;
  static const std::map<std::string, PREDEFINED_DICTIONARY_NAME> m{
      {"4X4_50", DICT_4X4_50},   {"4X4_100", DICT_4X4_100},   {"4X4_250", DICT_4X4_250},
      {"5X5_50", DICT_5X5_50},   {"5X5_100", DICT_5X5_100},   {"5X5_250", DICT_5X5_250},
      {"6X6_50", DICT_6X6_50},   {"6X6_100", DICT_6X6_100},   {"6X6_250", DICT_6X6_250},
      {"APRILTAG_36h11", DICT_APRILTAG_36h11},
  };
  return m;
}

cv::Ptr<cv::aruco::Dictionary> dictionary(const std::string& name) {
  auto it = dictionaries().find(name);
  return it == dictionaries().end() ? nullptr : cv::aruco::getPredefinedDictionary(it->second);
}

constexpr double kPageW = 210.0, kPageH = 297.0, kMargin = 15.0;  // A4, mm
constexpr double kLabelMm = 8.0;                                  // room under a marker for its id

// Where each marker goes (its top-left corner, mm from the page's top-left). false + error when they do not fit.
bool layout(const SheetOptions& o, std::vector<cv::Point2d>& out, std::string& error) {
  if (!(o.marker_mm >= 10 && o.marker_mm <= 180)) {
    error = "marker size must be 10..180 mm";
    return false;
  }
  if (o.ids.empty()) {
    error = "no marker ids";
    return false;
  }
  const double gap = std::max(10.0, o.marker_mm * 0.5);  // white quiet zone between markers
  const double cell_w = o.marker_mm + gap, cell_h = o.marker_mm + gap + kLabelMm;
  int cols = int((kPageW - 2 * kMargin + gap) / cell_w);
  int rows = int((kPageH - 2 * kMargin - 20 /* scale bar */ + gap) / cell_h);
  if (cols < 1 || rows < 1 || size_t(cols * rows) < o.ids.size()) {
    error = std::to_string(o.ids.size()) + " markers of " + std::to_string(int(o.marker_mm)) + " mm do not fit on A4 (" +
            std::to_string(std::max(0, cols * rows)) + " do)";
    return false;
  }
  out.clear();
  for (size_t i = 0; i < o.ids.size(); ++i)
    out.push_back({kMargin + double(i % cols) * cell_w, kMargin + 20 + double(i / cols) * cell_h});
  return true;
}

uint32_t crc32(const unsigned char* p, size_t n, uint32_t crc = 0xffffffffu) {
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return crc;
}

void put_be32(std::string& s, uint32_t v) {
  for (int i = 3; i >= 0; --i) s.push_back(char((v >> (8 * i)) & 0xff));
}

// Inserts a pHYs chunk (pixels per metre) right after IHDR: printers then know the true size.
std::string with_phys(const std::vector<uchar>& png, int dpi) {
  const size_t ihdr_end = 8 + 4 + 4 + 13 + 4;  // signature, IHDR length, type, data, CRC
  std::string chunk;
  uint32_t ppm = uint32_t(std::lround(dpi / 0.0254));
  std::string body = "pHYs";
  put_be32(body, ppm);
  put_be32(body, ppm);
  body.push_back(1);  // unit: metre
  put_be32(chunk, 9);
  chunk += body;
  put_be32(chunk, crc32(reinterpret_cast<const unsigned char*>(body.data()), body.size()) ^ 0xffffffffu);
  std::string out(png.begin(), png.begin() + long(ihdr_end));
  out += chunk;
  out.append(png.begin() + long(ihdr_end), png.end());
  return out;
}

}  // namespace

bool marker_dictionary_known(const std::string& name) { return dictionaries().count(name) != 0; }

std::string marker_dictionary_names() {
  std::string s;
  for (const auto& [k, v] : dictionaries()) s += (s.empty() ? "" : ", ") + k;
  return s;
}

bool marker_cells(const std::string& dict_name, int id, cv::Mat& cells, std::string& error) {
  auto dict = dictionary(dict_name);
  if (!dict) {
    error = "unknown ArUco dictionary \"" + dict_name + "\" (known: " + marker_dictionary_names() + ")";
    return false;
  }
  if (id < 0 || id >= dict->bytesList.rows) {
    error = "marker id " + std::to_string(id) + " is not in " + dict_name + " (0.." + std::to_string(dict->bytesList.rows - 1) + ")";
    return false;
  }
  cv::aruco::drawMarker(dict, id, dict->markerSize + 2, cells, 1);
  return true;
}

bool write_marker_sheet_png(const std::string& path, const SheetOptions& o, std::string& error) {
  std::vector<cv::Point2d> at;
  if (!layout(o, at, error)) return false;
  if (o.dpi < 72 || o.dpi > 1200) {
    error = "dpi must be 72..1200";
    return false;
  }
  const double px_mm = o.dpi / 25.4;
  cv::Mat page(int(std::lround(kPageH * px_mm)), int(std::lround(kPageW * px_mm)), CV_8U, cv::Scalar(255));
  auto px = [&](double mm) { return int(std::lround(mm * px_mm)); };
  for (size_t i = 0; i < o.ids.size(); ++i) {
    cv::Mat cells;
    if (!marker_cells(o.dictionary, o.ids[i], cells, error)) return false;
    const int n = cells.rows;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        if (cells.at<uchar>(r, c)) continue;
        double x0 = at[i].x + o.marker_mm * c / n, y0 = at[i].y + o.marker_mm * r / n;
        cv::rectangle(page, cv::Point(px(x0), px(y0)),
                      cv::Point(px(x0 + o.marker_mm / n) - 1, px(y0 + o.marker_mm / n) - 1), cv::Scalar(0), cv::FILLED);
      }
    std::string label = "id " + std::to_string(o.ids[i]) + "  (" + o.dictionary + ", " + std::to_string(int(o.marker_mm)) + " mm)";
    cv::putText(page, label, cv::Point(px(at[i].x), px(at[i].y + o.marker_mm + 6)), cv::FONT_HERSHEY_SIMPLEX,
                px_mm * 0.12, cv::Scalar(0), std::max(1, int(px_mm * 0.25)));
  }
  // Scale bar: 100 mm, to check the printer kept the size.
  cv::rectangle(page, cv::Point(px(kMargin), px(kMargin)), cv::Point(px(kMargin + 100) - 1, px(kMargin + 2) - 1),
                cv::Scalar(0), cv::FILLED);
  cv::putText(page, "100 mm: print at 100 % (no fit to page)", cv::Point(px(kMargin), px(kMargin + 8)),
              cv::FONT_HERSHEY_SIMPLEX, px_mm * 0.12, cv::Scalar(0), std::max(1, int(px_mm * 0.25)));
  std::vector<uchar> png;
  if (!cv::imencode(".png", page, png)) {
    error = path + ": PNG encoding failed";
    return false;
  }
  return rbx1::write_file_atomic(path, with_phys(png, o.dpi), error);
}

bool write_marker_sheet_pdf(const std::string& path, const SheetOptions& o, std::string& error) {
  std::vector<cv::Point2d> at;
  if (!layout(o, at, error)) return false;
  const double pt = 72.0 / 25.4;  // points per mm
  char buf[160];
  std::string content;
  // PDF's origin is the page's bottom-left, y up.
  auto rect = [&](double x_mm, double y_mm, double w_mm, double h_mm) {
    std::snprintf(buf, sizeof buf, "%.3f %.3f %.3f %.3f re\n", x_mm * pt, (kPageH - y_mm - h_mm) * pt, w_mm * pt, h_mm * pt);
    content += buf;
  };
  auto text = [&](double x_mm, double y_mm, const std::string& s) {
    std::snprintf(buf, sizeof buf, "BT /F1 9 Tf %.3f %.3f Td (", x_mm * pt, (kPageH - y_mm) * pt);
    content += buf + s + ") Tj ET\n";
  };
  content += "0 g\n";
  for (size_t i = 0; i < o.ids.size(); ++i) {
    cv::Mat cells;
    if (!marker_cells(o.dictionary, o.ids[i], cells, error)) return false;
    const int n = cells.rows;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c)
        if (!cells.at<uchar>(r, c)) rect(at[i].x + o.marker_mm * c / n, at[i].y + o.marker_mm * r / n, o.marker_mm / n, o.marker_mm / n);
    content += "f\n";
    text(at[i].x, at[i].y + o.marker_mm + 5, "id " + std::to_string(o.ids[i]) + "  (" + o.dictionary + ", " +
                                                  std::to_string(int(o.marker_mm)) + " mm)");
  }
  rect(kMargin, kMargin, 100, 2);
  content += "f\n";
  text(kMargin, kMargin + 7, "100 mm: print at 100 % (no fit to page)");

  std::vector<std::string> objects = {
      "<< /Type /Catalog /Pages 2 0 R >>",
      "<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
      "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 595.276 841.890] /Contents 4 0 R "
      "/Resources << /Font << /F1 5 0 R >> >> >>",
      "<< /Length " + std::to_string(content.size()) + " >>\nstream\n" + content + "endstream",
      "<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica >>",
  };
  std::string pdf = "%PDF-1.4\n";
  std::vector<size_t> offsets;
  for (size_t i = 0; i < objects.size(); ++i) {
    offsets.push_back(pdf.size());
    pdf += std::to_string(i + 1) + " 0 obj\n" + objects[i] + "\nendobj\n";
  }
  size_t xref = pdf.size();
  pdf += "xref\n0 " + std::to_string(objects.size() + 1) + "\n0000000000 65535 f \n";
  for (size_t off : offsets) {
    std::snprintf(buf, sizeof buf, "%010zu 00000 n \n", off);
    pdf += buf;
  }
  pdf += "trailer\n<< /Size " + std::to_string(objects.size() + 1) + " /Root 1 0 R >>\nstartxref\n" +
         std::to_string(xref) + "\n%%EOF\n";
  return rbx1::write_file_atomic(path, pdf, error);
}

bool detect_markers(const cv::Mat& image, const std::string& dict_name, std::vector<DetectedMarker>& out,
                    std::vector<int>& duplicates, std::string& error) {
  auto dict = dictionary(dict_name);
  if (!dict) {
    error = "unknown ArUco dictionary \"" + dict_name + "\" (known: " + marker_dictionary_names() + ")";
    return false;
  }
  if (image.empty()) {
    error = "empty image";
    return false;
  }
  cv::Mat gray;
  if (image.channels() == 1) gray = image;
  else cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  auto params = cv::aruco::DetectorParameters::create();
  params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(gray, dict, corners, ids, params);
  std::map<int, int> count;
  for (int id : ids) count[id]++;
  out.clear();
  duplicates.clear();
  for (const auto& [id, n] : count)
    if (n > 1) duplicates.push_back(id);
  for (size_t i = 0; i < ids.size(); ++i) {
    if (count[ids[i]] > 1) continue;
    DetectedMarker m;
    m.id = ids[i];
    for (const auto& c : corners[i]) m.corners.push_back(c);
    // Diagonals c0-c2 and c1-c3 meet at the image of the square's centre.
    cv::Point2d a = m.corners[0], b = m.corners[2], c = m.corners[1], d = m.corners[3];
    cv::Point2d r = b - a, s = d - c;
    double den = r.x * s.y - r.y * s.x;
    double t = std::fabs(den) > 1e-12 ? ((c - a).x * s.y - (c - a).y * s.x) / den : 0.5;
    m.centre = a + t * r;
    out.push_back(m);
  }
  std::sort(out.begin(), out.end(), [](const DetectedMarker& x, const DetectedMarker& y) { return x.id < y.id; });
  return true;
}

}  // namespace rbx1::calib
