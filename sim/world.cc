#include "sim/world.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <utility>

#include "core/text_file.h"

namespace driftlab::sim {

Eigen::AlignedBox2d World::bounds() const {
  Eigen::AlignedBox2d out;
  for (const Box& b : boxes) {
    const double c = std::cos(b.yaw), s = std::sin(b.yaw);
    const Eigen::Vector2d half(0.5 * (std::abs(c) * b.size.x() + std::abs(s) * b.size.y()),
                               0.5 * (std::abs(s) * b.size.x() + std::abs(c) * b.size.y()));
    out.extend(Eigen::Vector2d(b.center.head<2>() - half));
    out.extend(Eigen::Vector2d(b.center.head<2>() + half));
  }
  for (const Cylinder& c : cylinders) {
    out.extend(Eigen::Vector2d(c.center.head<2>().array() - c.radius));
    out.extend(Eigen::Vector2d(c.center.head<2>().array() + c.radius));
  }
  return out;
}

namespace {

/// Thrown inside the parser only, caught in parse_world: keeps every check one line.
struct ParseError {
  std::string message;
};

class Parser {
 public:
  Parser(std::string origin, std::string base_dir) : origin_(std::move(origin)), base_dir_(std::move(base_dir)) {}

  World parse(const YAML::Node& root) {
    World world;
    if (!root || root.IsNull()) return world;
    if (!root.IsMap()) fail(root, "a world must be a map with friction, walls, boxes, cylinders, images");
    for (const auto& item : root) {
      const std::string key = item.first.as<std::string>();
      const YAML::Node& v = item.second;
      if (key == "friction") {
        world.friction = number(v, "friction");
        if (world.friction < 0) fail(v, "friction must be >= 0");
      } else if (key == "walls") {
        for (size_t i = 0; i < list(v, key).size(); ++i) wall(v[i], "walls[" + std::to_string(i) + "]", world);
      } else if (key == "boxes") {
        for (size_t i = 0; i < list(v, key).size(); ++i) box(v[i], "boxes[" + std::to_string(i) + "]", world);
      } else if (key == "cylinders") {
        for (size_t i = 0; i < list(v, key).size(); ++i) {
          cylinder(v[i], "cylinders[" + std::to_string(i) + "]", world);
        }
      } else if (key == "images") {
        for (size_t i = 0; i < list(v, key).size(); ++i) image(v[i], "images[" + std::to_string(i) + "]", world);
      } else {
        fail(item.first, "unknown key '" + key + "' (known: friction, walls, boxes, cylinders, images)");
      }
    }
    return world;
  }

 private:
  [[noreturn]] void fail(const YAML::Node& node, const std::string& what) const {
    throw ParseError{origin_ + ":" + std::to_string(node.Mark().line + 1) + ": " + what};
  }

  const YAML::Node& list(const YAML::Node& v, const std::string& key) const {
    if (!v.IsSequence()) fail(v, "'" + key + "' must be a list");
    return v;
  }

  /// The entries of a map, rejecting keys not in `known`.
  std::vector<std::pair<std::string, YAML::Node>> entries(const YAML::Node& v, const std::string& where,
                                                          std::initializer_list<const char*> known) const {
    if (!v.IsMap()) fail(v, where + " must be a map");
    std::vector<std::pair<std::string, YAML::Node>> out;
    for (const auto& item : v) {
      const std::string key = item.first.as<std::string>();
      bool ok = false;
      std::string names;
      for (const char* k : known) {
        ok = ok || key == k;
        names += (names.empty() ? "" : ", ") + std::string(k);
      }
      if (!ok) fail(item.first, "unknown key '" + key + "' in " + where + " (known: " + names + ")");
      out.emplace_back(key, item.second);
    }
    return out;
  }

  double number(const YAML::Node& v, const std::string& what) const {
    double x = 0;
    try {
      if (!v.IsScalar()) throw YAML::Exception(v.Mark(), "not a scalar");
      x = v.as<double>();
    } catch (const YAML::Exception&) {
      fail(v, what + " must be a number");
    }
    if (!std::isfinite(x)) fail(v, what + " must be finite");
    return x;
  }

  double positive(const YAML::Node& v, const std::string& what) const {
    const double x = number(v, what);
    if (x <= 0) fail(v, what + " must be > 0, not " + v.as<std::string>());
    return x;
  }

  /// A list of `n` numbers, or of `n` or `alt` numbers when alt > 0.
  std::vector<double> vec(const YAML::Node& v, const std::string& what, size_t n, size_t alt = 0) const {
    const std::string shape = alt > 0 ? std::to_string(n) + " or " + std::to_string(alt) : std::to_string(n);
    if (!v.IsSequence() || (v.size() != n && (alt == 0 || v.size() != alt))) {
      fail(v, what + " must be a list of " + shape + " numbers");
    }
    std::vector<double> out;
    for (size_t i = 0; i < v.size(); ++i) out.push_back(number(v[i], what + "[" + std::to_string(i) + "]"));
    return out;
  }

  std::array<uint8_t, 3> color(const YAML::Node& v, const std::string& what) const {
    if (!v.IsSequence() || v.size() != 3) fail(v, what + " must be [r, g, b] with each in 0..255");
    std::array<uint8_t, 3> out{};
    for (size_t i = 0; i < 3; ++i) {
      const double x = number(v[i], what);
      if (x < 0 || x > 255 || x != std::floor(x)) fail(v[i], what + " must be [r, g, b] with each in 0..255");
      out[i] = static_cast<uint8_t>(x);
    }
    return out;
  }

  std::string text(const YAML::Node& v, const std::string& what) const {
    if (!v.IsScalar()) fail(v, what + " must be a string");
    return v.as<std::string>();
  }

  void wall(const YAML::Node& v, const std::string& where, World& world) const {
    std::vector<double> from, to;
    double thickness = 0.1, height = 2.5;
    Box b;
    b.color = {200, 200, 200};
    b.name = "wall_" + std::to_string(world.boxes.size());
    for (const auto& [key, x] : entries(v, where, {"name", "from", "to", "thickness", "height", "color"})) {
      if (key == "name") b.name = text(x, where + ".name");
      if (key == "from") from = vec(x, where + ".from", 2);
      if (key == "to") to = vec(x, where + ".to", 2);
      if (key == "thickness") thickness = positive(x, where + ".thickness");
      if (key == "height") height = positive(x, where + ".height");
      if (key == "color") b.color = color(x, where + ".color");
    }
    if (from.empty() || to.empty()) fail(v, where + " needs 'from' and 'to'");
    const Eigen::Vector2d a(from[0], from[1]), c(to[0], to[1]);
    const double length = (c - a).norm();
    if (length <= 0) fail(v, where + " has 'from' equal to 'to'");
    // Extended by half the thickness at each end, so that walls meeting at a corner close it.
    b.size = Eigen::Vector3d(length + thickness, thickness, height);
    b.center = Eigen::Vector3d(0.5 * (a.x() + c.x()), 0.5 * (a.y() + c.y()), 0.5 * height);
    b.yaw = std::atan2(c.y() - a.y(), c.x() - a.x());
    world.boxes.push_back(std::move(b));
  }

  void box(const YAML::Node& v, const std::string& where, World& world) const {
    Box b;
    b.color = {170, 120, 70};
    b.name = "box_" + std::to_string(world.boxes.size());
    std::vector<double> center;
    bool has_size = false;
    for (const auto& [key, x] : entries(v, where, {"name", "center", "size", "yaw", "color"})) {
      if (key == "name") b.name = text(x, where + ".name");
      if (key == "center") center = vec(x, where + ".center", 2, 3);
      if (key == "yaw") b.yaw = number(x, where + ".yaw");
      if (key == "color") b.color = color(x, where + ".color");
      if (key == "size") {
        const auto s = vec(x, where + ".size", 3);
        for (size_t i = 0; i < 3; ++i) {
          if (s[i] <= 0) fail(x, where + ".size must be positive, got " + std::to_string(s[i]) + " in [" +
                                     std::to_string(i) + "]");
        }
        b.size = Eigen::Vector3d(s[0], s[1], s[2]);
        has_size = true;
      }
    }
    if (center.empty() || !has_size) fail(v, where + " needs 'center' and 'size'");
    b.center = Eigen::Vector3d(center[0], center[1], center.size() == 3 ? center[2] : 0.5 * b.size.z());
    world.boxes.push_back(std::move(b));
  }

  void cylinder(const YAML::Node& v, const std::string& where, World& world) const {
    Cylinder c;
    c.color = {90, 120, 170};
    c.name = "cylinder_" + std::to_string(world.cylinders.size());
    std::vector<double> center;
    for (const auto& [key, x] : entries(v, where, {"name", "center", "radius", "height", "color"})) {
      if (key == "name") c.name = text(x, where + ".name");
      if (key == "center") center = vec(x, where + ".center", 2, 3);
      if (key == "radius") c.radius = positive(x, where + ".radius");
      if (key == "height") c.height = positive(x, where + ".height");
      if (key == "color") c.color = color(x, where + ".color");
    }
    if (center.empty() || c.radius <= 0 || c.height <= 0) fail(v, where + " needs 'center', 'radius' and 'height'");
    c.center = Eigen::Vector3d(center[0], center[1], center.size() == 3 ? center[2] : 0.5 * c.height);
    world.cylinders.push_back(std::move(c));
  }

  void image(const YAML::Node& v, const std::string& where, World& world) const {
    std::string file;
    double resolution = 0, height = 2.5, threshold = 128;
    std::vector<double> origin{0, 0};
    std::array<uint8_t, 3> rgb{200, 200, 200};
    YAML::Node file_node;
    for (const auto& [key, x] : entries(v, where, {"file", "resolution", "origin", "height", "occupied_below", "color"})) {
      if (key == "file") file = text(x, where + ".file"), file_node = x;
      if (key == "resolution") resolution = positive(x, where + ".resolution");
      if (key == "origin") origin = vec(x, where + ".origin", 2);
      if (key == "height") height = positive(x, where + ".height");
      if (key == "color") rgb = color(x, where + ".color");
      if (key == "occupied_below") {
        threshold = number(x, where + ".occupied_below");
        if (threshold < 0 || threshold > 256) fail(x, where + ".occupied_below must be in 0..256");
      }
    }
    if (file.empty() || resolution <= 0) fail(v, where + " needs 'file' and 'resolution'");
    std::filesystem::path path(file);
    if (path.is_relative() && !base_dir_.empty()) path = std::filesystem::path(base_dir_) / path;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) fail(file_node, where + ".file: no image at " + path.string());
    cv::Mat gray;
    try {
      gray = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception& e) {
      gray.release();
    }
    if (gray.empty()) fail(file_node, where + ".file: cannot read " + path.string() + " as an image");
    const size_t first = world.boxes.size();
    // Each box is a Bullet object: a 3000x3000 checkerboard made 4.5 million of them.
    if (!extrude(gray, resolution, Eigen::Vector2d(origin[0], origin[1]), height, threshold, rgb, world.boxes,
                 first + kMaxImageBoxes)) {
      world.boxes.resize(first);
      fail(file_node, where + ".file: " + path.string() + " (" + std::to_string(gray.cols) + "x" +
                          std::to_string(gray.rows) + ") needs more than " + std::to_string(kMaxImageBoxes) +
                          " boxes (its occupied pixels merged into rectangles by rows and runs): give an image with "
                          "larger occupied areas, or fewer pixels");
    }
    for (size_t i = first; i < world.boxes.size(); ++i) {
      world.boxes[i].name = "image_" + where.substr(where.find('[') + 1, where.find(']') - where.find('[') - 1) +
                            "_" + std::to_string(i - first);
    }
  }

  /// The most boxes one image may become.
  static constexpr size_t kMaxImageBoxes = 100'000;

  /// Occupied pixels (darker than `threshold`) as few boxes: runs of a row, and equal runs of consecutive rows
  /// merged into one rectangle. False, as soon as out would hold more than max_boxes.
  static bool extrude(const cv::Mat& gray, double res, const Eigen::Vector2d& origin, double height, double threshold,
                      const std::array<uint8_t, 3>& rgb, std::vector<Box>& out, size_t max_boxes) {
    struct Rect {
      int c0, c1, r0;  // columns [c0, c1), first row r0
    };
    const int rows = gray.rows, cols = gray.cols;
    auto emit = [&](const Rect& r, int r1) {  // rows [r.r0, r1)
      Box b;
      b.size = Eigen::Vector3d((r.c1 - r.c0) * res, (r1 - r.r0) * res, height);
      b.center = Eigen::Vector3d(origin.x() + 0.5 * (r.c0 + r.c1) * res,
                                 origin.y() + (rows - 0.5 * (r.r0 + r1)) * res, 0.5 * height);
      b.color = rgb;
      out.push_back(std::move(b));
    };
    std::vector<Rect> open, next;
    for (int r = 0; r <= rows; ++r) {
      next.clear();
      size_t k = 0;  // open rectangles are sorted by c0, like this row's runs
      const uint8_t* px = r < rows ? gray.ptr<uint8_t>(r) : nullptr;
      for (int c = 0; px != nullptr && c < cols;) {
        if (px[c] >= threshold) {
          ++c;
          continue;
        }
        const int c0 = c;
        while (c < cols && px[c] < threshold) ++c;
        while (k < open.size() && open[k].c0 < c0) emit(open[k], r), ++k;
        if (k < open.size() && open[k].c0 == c0 && open[k].c1 == c) {
          next.push_back(open[k++]);
        } else {
          next.push_back({c0, c, r});
        }
      }
      while (k < open.size()) emit(open[k], r), ++k;
      std::swap(open, next);
      if (out.size() + open.size() > max_boxes) return false;
    }
    return true;
  }

  std::string origin_;
  std::string base_dir_;
};

}  // namespace

Result<World> parse_world(const std::string& yaml_text, const std::string& origin, const std::string& base_dir) {
  try {
    YAML::Node root = YAML::Load(yaml_text);
    return Parser(origin, base_dir).parse(root);
  } catch (const ParseError& e) {
    return Error{e.message};
  } catch (const YAML::Exception& e) {
    return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  } catch (const std::exception& e) {
    return Error{origin + ": " + e.what()};
  }
}

Result<World> load_world(const std::string& path) {
  auto text = read_text_file(path, "world description");
  if (!text) return text.error();
  return parse_world(*text, path, std::filesystem::path(path).parent_path().string());
}

}  // namespace driftlab::sim
