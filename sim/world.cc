#include "sim/world.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <utility>

#include "core/config.h"
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

/// The most boxes one image may become (each is a Bullet object: a 3000x3000 checkerboard made 4.5 million).
constexpr size_t kMaxImageBoxes = 100'000;

/// Occupied pixels (darker than `threshold`) as few boxes: runs of a row, and equal runs of consecutive rows
/// merged into one rectangle. False, as soon as out would hold more than max_boxes.
bool extrude(const cv::Mat& gray, double res, const Eigen::Vector2d& origin, double height, double threshold,
             const std::array<uint8_t, 3>& rgb, std::vector<Box>& out, size_t max_boxes) {
  struct Rect {
    int c0, c1, r0;  // columns [c0, c1), first row r0
  };
  const int rows = gray.rows, cols = gray.cols;
  auto emit = [&](const Rect& r, int r1) {  // rows [r.r0, r1)
    Box b;
    b.size = Eigen::Vector3d((r.c1 - r.c0) * res, (r1 - r.r0) * res, height);
    b.center = Eigen::Vector3d(origin.x() + 0.5 * (r.c0 + r.c1) * res, origin.y() + (rows - 0.5 * (r.r0 + r1)) * res,
                               0.5 * height);
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

using config::Value;
using Rgb = std::array<uint8_t, 3>;

/// The world file's entries as written, before they become boxes and cylinders.
struct WallEntry {
  std::string name;
  std::array<double, 2> from{}, to{};
  double thickness = 0.1, height = 2.5;
  Rgb color{200, 200, 200};
};
struct BoxEntry {
  std::string name;
  std::vector<double> center;  ///< x, y [, z]
  std::array<double, 3> size{};
  double yaw = 0;
  Rgb color{170, 120, 70};
};
struct CylinderEntry {
  std::string name;
  std::vector<double> center;  ///< x, y [, z]
  double radius = 0, height = 0;
  Rgb color{90, 120, 170};
};
struct ImageEntry {
  std::string file;
  double resolution = 0, height = 2.5, occupied_below = 128;
  std::array<double, 2> origin{0, 0};
  Rgb color{200, 200, 200};
  std::optional<Value> file_value;  ///< where `file` is, for the image's own errors
};
struct WorldFile {
  double friction = 0.8;
  std::vector<WallEntry> walls;
  std::vector<BoxEntry> boxes;
  std::vector<CylinderEntry> cylinders;
  std::vector<ImageEntry> images;
};

Status read_color(const Value& v, Rgb& out) {
  const std::string what = "must be [r, g, b] with each in 0..255";
  if (!v.node().IsSequence() || v.node().size() != 3) return v.error(what);
  for (size_t i = 0; i < 3; ++i) {
    auto x = v[i].number(config::between(0, 255));
    if (!x || *x != std::floor(*x)) return v.error(what);
    out[i] = static_cast<uint8_t>(*x);
  }
  return {};
}
std::string show_color(const Rgb& c) {
  return "[" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + "]";
}

/// x, y and, when given, z.
Status read_center(const Value& v, std::vector<double>& out) {
  const size_t n = v.node().IsSequence() ? v.node().size() : 0;
  if (n != 2 && n != 3) return v.error("must be a list of 2 or 3 numbers");
  auto x = v.numbers(n, {}, "m");
  if (!x) return x.error();
  out = std::move(*x);
  return {};
}

template <class E>
config::Table<E>& color_key(config::Table<E>& t) {
  return t.template custom<Rgb>("color", &E::color, "[r, g, b]", "", "0..255 each", "its color in the camera's images",
                                read_color, show_color);
}

/// A list of entries, each read with `table`.
template <class E>
std::function<Status(const Value&, std::vector<E>&)> entries_of(const config::Table<E>& table) {
  return [&table](const Value& v, std::vector<E>& out) -> Status {
    if (!v.given()) return {};
    if (!v.node().IsSequence()) return v.error("must be a list");
    for (size_t i = 0; i < v.node().size(); ++i) {
      E e;
      if (Status s = table.read(v[i], e); !s) return s;
      out.push_back(std::move(e));
    }
    return {};
  };
}

const config::Table<WallEntry>& wall_table() {
  static const auto table = [] {
    config::Table<WallEntry> wall;
    wall.text("name", &WallEntry::name, "its name (N: its place among the boxes, or the cylinders)")
        .shown_default("wall_N")
        .numbers("from", &WallEntry::from, {}, "m", "x, y of one end")
        .required()
        .numbers("to", &WallEntry::to, {}, "m", "x, y of the other")
        .required()
        .number("thickness", &WallEntry::thickness, config::above(0), "m",
                "its thickness (it extends by half of it past each end)")
        .number("height", &WallEntry::height, config::above(0), "m", "its height");
    color_key(wall).check([](const Value& map, WallEntry& w) -> Status {
      if (w.from == w.to) return map.error("has 'from' equal to 'to'");
      return {};
    });
    return wall;
  }();
  return table;
}

const config::Table<BoxEntry>& box_table() {
  static const auto table = [] {
    config::Table<BoxEntry> box;
    box.text("name", &BoxEntry::name, "its name (N: its place among the boxes, or the cylinders)")
        .shown_default("box_N")
        .custom<std::vector<double>>("center", &BoxEntry::center, "[2 or 3 numbers]", "m", "",
                                     "x, y of its centre, and z (default: half its height: on the floor)", read_center,
                                     [](const std::vector<double>&) { return std::string(); })
        .required()
        .numbers("size", &BoxEntry::size, config::above(0), "m", "its length, width and height")
        .required()
        .number("yaw", &BoxEntry::yaw, {}, "rad", "its heading");
    color_key(box);
    return box;
  }();
  return table;
}

const config::Table<CylinderEntry>& cylinder_table() {
  static const auto table = [] {
    config::Table<CylinderEntry> cylinder;
    cylinder.text("name", &CylinderEntry::name, "its name (N: its place among the boxes, or the cylinders)")
        .shown_default("cylinder_N")
        .custom<std::vector<double>>("center", &CylinderEntry::center, "[2 or 3 numbers]", "m", "",
                                     "x, y of its axis, and z of its centre (default: half its height)", read_center,
                                     [](const std::vector<double>&) { return std::string(); })
        .required()
        .number("radius", &CylinderEntry::radius, config::above(0), "m", "its radius")
        .required()
        .number("height", &CylinderEntry::height, config::above(0), "m", "its height")
        .required();
    color_key(cylinder);
    return cylinder;
  }();
  return table;
}

const config::Table<ImageEntry>& image_table() {
  static const auto table = [] {
    config::Table<ImageEntry> image;
    image.text("file", &ImageEntry::file, "an occupancy image (relative to the world file)", config::Text::kNonEmpty)
        .required()
        .number("resolution", &ImageEntry::resolution, config::above(0), "m", "the side of a pixel")
        .required()
        .numbers("origin", &ImageEntry::origin, {}, "m", "x, y of the image's lower left corner")
        .number("height", &ImageEntry::height, config::above(0), "m", "the height of what is occupied")
        .number("occupied_below", &ImageEntry::occupied_below, config::between(0, 256), "",
                "a pixel darker than this (0..255 gray) is occupied");
    color_key(image).check([](const Value& map, ImageEntry& e) -> Status {
      e.file_value = map["file"];
      return {};
    });
    return image;
  }();
  return table;
}

const config::Table<WorldFile>& world_table() {
  static const auto table = [] {
    config::Table<WorldFile> t;
    t.describe("A world: the floor's friction and the obstacles on it (docs/worlds.md).")
        .number("friction", &WorldFile::friction, config::at_least(0), "",
                "Coulomb friction of the floor and of every obstacle")
        .custom<std::vector<WallEntry>>("walls", &WorldFile::walls, "list", "", "", "walls from one point to another",
                                        entries_of(wall_table()), [](const auto&) { return std::string(); })
        .shown_default("none")
        .custom<std::vector<BoxEntry>>("boxes", &WorldFile::boxes, "list", "", "", "boxes", entries_of(box_table()),
                                       [](const auto&) { return std::string(); })
        .shown_default("none")
        .custom<std::vector<CylinderEntry>>("cylinders", &WorldFile::cylinders, "list", "", "", "upright cylinders",
                                            entries_of(cylinder_table()), [](const auto&) { return std::string(); })
        .shown_default("none")
        .custom<std::vector<ImageEntry>>("images", &WorldFile::images, "list", "", "",
                                         "occupancy images extruded into boxes", entries_of(image_table()),
                                         [](const auto&) { return std::string(); })
        .shown_default("none");
    return t;
  }();
  return table;
}

/// The image's occupied pixels as boxes. Errors name the image's file.
Status add_image(const ImageEntry& e, size_t index, const std::string& base_dir, World& world) {
  std::filesystem::path path(e.file);
  if (path.is_relative() && !base_dir.empty()) path = std::filesystem::path(base_dir) / path;
  const Value& at = *e.file_value;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return at.error("no image at " + path.string());
  cv::Mat gray;
  try {
    gray = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& e) {
    gray.release();
  }
  if (gray.empty()) return at.error("cannot read " + path.string() + " as an image");
  const size_t first = world.boxes.size();
  if (!extrude(gray, e.resolution, Eigen::Vector2d(e.origin[0], e.origin[1]), e.height, e.occupied_below, e.color,
               world.boxes, first + kMaxImageBoxes)) {
    world.boxes.resize(first);
    return at.error(path.string() + " (" + std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                    ") needs more than " + std::to_string(kMaxImageBoxes) +
                    " boxes (its occupied pixels merged into rectangles by rows and runs): give an image with larger "
                    "occupied areas, or fewer pixels");
  }
  for (size_t i = first; i < world.boxes.size(); ++i) {
    world.boxes[i].name = "image_" + std::to_string(index) + "_" + std::to_string(i - first);
  }
  return {};
}

/// The entries as the world's boxes and cylinders, in the order of the file's keys (the order of the Bullet
/// objects, and of the default names).
Result<World> build(const WorldFile& f, const YAML::Node& root, const std::string& base_dir) {
  World world;
  world.friction = f.friction;
  std::vector<std::string> keys;
  if (root.IsMap()) {
    for (const auto& kv : root) keys.push_back(kv.first.Scalar());
  }
  for (const std::string& key : keys) {
    if (key == "walls") {
      for (const WallEntry& w : f.walls) {
        Box b;
        b.name = w.name.empty() ? "wall_" + std::to_string(world.boxes.size()) : w.name;
        b.color = w.color;
        const Eigen::Vector2d a(w.from[0], w.from[1]), c(w.to[0], w.to[1]);
        // Extended by half the thickness at each end, so that walls meeting at a corner close it.
        b.size = Eigen::Vector3d((c - a).norm() + w.thickness, w.thickness, w.height);
        b.center = Eigen::Vector3d(0.5 * (a.x() + c.x()), 0.5 * (a.y() + c.y()), 0.5 * w.height);
        b.yaw = std::atan2(c.y() - a.y(), c.x() - a.x());
        world.boxes.push_back(std::move(b));
      }
    } else if (key == "boxes") {
      for (const BoxEntry& e : f.boxes) {
        Box b;
        b.name = e.name.empty() ? "box_" + std::to_string(world.boxes.size()) : e.name;
        b.color = e.color;
        b.yaw = e.yaw;
        b.size = Eigen::Vector3d(e.size[0], e.size[1], e.size[2]);
        b.center = Eigen::Vector3d(e.center[0], e.center[1], e.center.size() == 3 ? e.center[2] : 0.5 * b.size.z());
        world.boxes.push_back(std::move(b));
      }
    } else if (key == "cylinders") {
      for (const CylinderEntry& e : f.cylinders) {
        Cylinder c;
        c.name = e.name.empty() ? "cylinder_" + std::to_string(world.cylinders.size()) : e.name;
        c.color = e.color;
        c.radius = e.radius;
        c.height = e.height;
        c.center = Eigen::Vector3d(e.center[0], e.center[1], e.center.size() == 3 ? e.center[2] : 0.5 * e.height);
        world.cylinders.push_back(std::move(c));
      }
    } else if (key == "images") {
      for (size_t i = 0; i < f.images.size(); ++i) {
        if (Status s = add_image(f.images[i], i, base_dir, world); !s) return s.error();
      }
    }
  }
  return world;
}

}  // namespace

std::string world_reference() {
  return world_table().reference() + "\nEach of `walls`:\n\n" + wall_table().reference() + "\nEach of `boxes`:\n\n" +
         box_table().reference() + "\nEach of `cylinders`:\n\n" + cylinder_table().reference() +
         "\nEach of `images` (pixels darker than `occupied_below` become boxes):\n\n" + image_table().reference();
}

Result<World> parse_world(const std::string& yaml_text, const std::string& origin, const std::string& base_dir) {
  auto root = config::parse_yaml(yaml_text, origin);
  if (!root) return root.error();
  WorldFile f;
  if (Status s = world_table().read(Value(*root, origin), f); !s) return s.error();
  return build(f, *root, base_dir);
}

Result<World> load_world(const std::string& path) {
  auto text = read_text_file(path, "world description");
  if (!text) return text.error();
  return parse_world(*text, path, std::filesystem::path(path).parent_path().string());
}

}  // namespace driftlab::sim
