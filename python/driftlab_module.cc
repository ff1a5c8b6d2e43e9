// _driftlab: the C++ side of `import driftlab` (python/driftlab/__init__.py is the package users see). Logs are
// opened as every command opens them (recordings/log_input.h: another tool's recording through its cached conversion),
// channels decoded by plans compiled per type (python/read_channel.h) straight into buffers NumPy takes over (an
// intact log read through a buffer, a pass per core, each decoding its share of the channels; a damaged one mapped
// once, at the first read, and kept while the Log lives), and diagnose, eval and import run in-process: diagnose and
// import through the library functions the commands call, eval through the command itself (its CLI11 options, built
// from keyword arguments by the package) with its output and its one-line error captured (apps/cli_util.h
// OutputCapture). The GIL is released while C++ works.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <CLI/CLI.hpp>

#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "analyzers/diagnosis_json.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "apps/diagnose_ranges.h"
#include "core/log_index.h"
#include "core/same_file.h"
#include "formats/import.h"
#include "lcmtypes/type_registry.h"
#include "python/read_channel.h"
#include "recordings/log_input.h"

namespace py = pybind11;

namespace driftlab::python {
namespace {

/// Raised as driftlab.Error, with the CLI's one-line message.
struct DriftlabError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

template <typename T>
T value_or_raise(Result<T> r) {
  if (!r) throw DriftlabError(r.error().message);
  return std::move(*r);
}

/// A vector handed to NumPy without a copy: the array owns it through a capsule.
template <typename Vector>
py::array adopt(Vector&& v, const py::dtype& dtype, std::vector<py::ssize_t> shape) {
  auto* owned = new Vector(std::forward<Vector>(v));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<Vector*>(p); });
  return py::array(dtype, std::move(shape), {}, owned->data(), free_when_done);
}

py::dtype dtype_of(const Column& c) {
  return py::dtype(std::string(1, c.kind == 'b' ? '?' : c.kind) + (c.kind == 'b' ? "" : std::to_string(c.item_bytes)));
}

/// The cells of an object array (object_array()), in column memory (a large one on huge pages, faulted in 2 MiB at
/// a time, where NumPy's own would be faulted in 4 KiB at a time): each holds a reference to its object, dropped
/// with the cells.
struct ObjectCells {
  explicit ObjectCells(size_t count)
      : n(count), cells(static_cast<PyObject**>(allocate_column(n * sizeof(PyObject*)))) {
    std::memset(cells, 0, n * sizeof(PyObject*));
  }
  ObjectCells(const ObjectCells&) = delete;
  ObjectCells& operator=(const ObjectCells&) = delete;
  ~ObjectCells() {
    for (size_t k = 0; k < n; ++k) Py_XDECREF(cells[k]);
    free_column(cells, n * sizeof(PyObject*));
  }
  size_t n;
  PyObject** cells;
};

/// An object array of n cells, each empty (NULL) until set_cell() fills it: all are, before it is handed out.
py::array object_array(size_t n) {
  auto* owned = new ObjectCells(n);
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<ObjectCells*>(p); });
  return {py::dtype("O"), std::vector<py::ssize_t>{static_cast<py::ssize_t>(n)}, {}, owned->cells, free_when_done};
}

/// Puts value into cell m of an object array (object_array()).
void set_cell(py::array& a, size_t m, py::object value) {
  auto** cells = static_cast<PyObject**>(a.mutable_data());
  Py_XDECREF(cells[m]);
  cells[m] = value.release().ptr();
}

/// A column as NumPy: 1-D for a scalar field, (messages, dims...) when every message holds as many elements, else
/// an object array of 1-D arrays (or of lists of strings).
py::object column_array(Column&& c, size_t messages) {
  bool same = true;
  const int64_t first = !c.counts.empty() ? c.counts[0] : messages > 0 ? c.fixed_count : 0;
  for (int64_t n : c.counts) same = same && n == first;
  std::vector<py::ssize_t> shape = {static_cast<py::ssize_t>(messages)};
  if (same && !(first == 1 && c.dims.empty())) {
    int64_t product = 1;
    for (size_t d : c.dims) product *= static_cast<int64_t>(d);
    if (!c.dims.empty() && product == first) {
      for (size_t d : c.dims) shape.push_back(static_cast<py::ssize_t>(d));
    } else {
      shape.push_back(first);
    }
  }
  if (c.kind == 'O') {
    py::array out = object_array(messages);
    size_t at = 0;
    // A string kept once (Strings: a frame name, message after message) is one str.
    std::vector<py::object> made(c.strings.distinct().size());
    const auto text = [&](size_t element) {
      py::object& s = made[c.strings.id(element)];
      if (!s) s = py::str(c.strings.distinct()[c.strings.id(element)]);
      return s;
    };
    for (size_t m = 0; m < messages; ++m) {
      if (same && first == 1) {
        set_cell(out, m, text(at++));
        continue;
      }
      const int64_t n = c.counts.empty() ? c.fixed_count : c.counts[m];
      py::list l(n);
      for (int64_t k = 0; k < n; ++k) PyList_SET_ITEM(l.ptr(), k, text(at++).release().ptr());
      set_cell(out, m, std::move(l));
    }
    return out;
  }
  const py::dtype dtype = dtype_of(c);
  if (same) return adopt(std::move(c.data), dtype, shape);
  py::array out = object_array(messages);
  size_t at = 0;
  for (size_t m = 0; m < messages; ++m) {
    const size_t bytes = static_cast<size_t>(c.counts[m]) * c.item_bytes;
    py::array a(dtype, std::vector<py::ssize_t>{static_cast<py::ssize_t>(c.counts[m])});
    if (bytes > 0) std::memcpy(a.mutable_data(), c.data.data() + at, bytes);
    at += bytes;
    set_cell(out, m, std::move(a));
  }
  return out;
}

/// An opened log: the LCM log read (the conversion of another tool's recording) and its index.
class Log {
 public:
  explicit Log(std::vector<std::string> inputs) : inputs_(std::move(inputs)) {
    py::gil_scoped_release release;
    lcm_path_ = value_or_raise(recordings::event_log_for(inputs_));
    index_ = std::make_shared<LogIndex>(value_or_raise(LogIndex::load_or_build(lcm_path_)));
  }

  std::string path() const { return inputs_[0]; }
  const std::string& lcm_path() const { return lcm_path_; }

  std::vector<std::string> channels() const {
    std::vector<std::string> names;
    names.reserve(index_->summary().channels.size());
    for (const auto& c : index_->summary().channels) names.push_back(c.name);
    return names;
  }

  const ChannelSummary& summary(const std::string& channel) const {
    for (const auto& c : index_->summary().channels) {
      if (c.name == channel) return c;
    }
    throw py::key_error(path() + ": no channel '" + channel + "'");
  }

  py::dict info() const {
    py::dict out;
    for (const auto& c : index_->summary().channels) {
      const char* type = lcmtypes::type_name(c.fingerprint);
      py::dict d;
      d["type"] = type != nullptr ? py::object(py::str(type)) : py::object(py::none());
      d["count"] = c.count;
      d["bytes"] = c.bytes;
      d["first_arrival"] = c.first_utime;
      d["last_arrival"] = c.last_utime;
      out[py::str(c.name)] = d;
    }
    return out;
  }

  py::dict read(const std::string& channel) const {
    summary(channel);  // a KeyError for an unknown channel
    return read_many(std::vector<std::string>{channel}, 0)[py::str(channel)].cast<py::dict>();
  }

  /// Channels read together: {channel: read(channel)}. Without names, every channel of a driftlab type. threads:
  /// the passes over an intact log at once (0: one per core; the tests ask for several on small logs).
  py::dict read_many(const std::optional<std::vector<std::string>>& names, size_t threads) const {
    return read_many_with(names, false, threads);
  }

  /// read_many() through the reference decode (lcmtypes::walk over a LogReader pass), for the tests to hold the
  /// decode plans to.
  py::dict read_reference(const std::optional<std::vector<std::string>>& names) const {
    return read_many_with(names, true, 1);
  }

 private:
  py::dict read_many_with(const std::optional<std::vector<std::string>>& names, bool reference, size_t threads) const {
    std::vector<std::pair<std::string, int64_t>> wanted;
    if (names) {
      for (const auto& n : *names) wanted.emplace_back(n, summary(n).count);
    } else {
      for (const auto& c : index_->summary().channels) {
        if (lcmtypes::type_name(c.fingerprint) != nullptr) wanted.emplace_back(c.name, c.count);
      }
    }
    py::dict out;
    if (reference) {
      Result<std::vector<Channel>> r = Error{""};
      {
        py::gil_scoped_release release;
        r = read_channels_reference(lcm_path_, wanted);
      }
      std::vector<Channel> channels = value_or_raise(std::move(r));
      for (size_t k = 0; k < channels.size(); ++k) out[py::str(wanted[k].first)] = to_dict(std::move(channels[k]));
      return out;
    }
    // An intact log: a pass over it per core, each through a buffer, each decoding its share of the channels (so
    // that the cores share the decoding and the faulting in of the columns' fresh pages).
    std::vector<uint64_t> bytes;
    bytes.reserve(wanted.size());
    for (const auto& channel : wanted) bytes.push_back(summary(channel.first).bytes);
    Result<std::optional<std::vector<Channel>>> r = Error{""};
    {
      py::gil_scoped_release release;
      const size_t passes = threads > 0 ? threads : std::min(8u, std::thread::hardware_concurrency());
      r = read_intact_log(lcm_path_, wanted, bytes, passes);
    }
    if (std::optional<std::vector<Channel>> channels = value_or_raise(std::move(r))) {
      for (size_t k = 0; k < channels->size(); ++k) out[py::str(wanted[k].first)] = to_dict(std::move((*channels)[k]));
      return out;
    }
    // A damaged log: its events found as LogReader finds them past the damage, once; then a channel at a time, each
    // made NumPy arrays while its strings are still in the cache and before the next one's buffers are allocated.
    for (const auto& channel : wanted) {
      Result<std::vector<Channel>> one = Error{""};
      {
        py::gil_scoped_release release;
        one = read_channels(*events(), {channel});
      }
      out[py::str(channel.first)] = to_dict(std::move(value_or_raise(std::move(one)).front()));
    }
    return out;
  }

  /// The log mapped, with where each channel's events are: built by the first read, kept for the next ones.
  /// Called without the GIL.
  std::shared_ptr<const EventTable> events() const {
    std::lock_guard<std::mutex> lock(events_mutex_);
    if (!events_) events_ = value_or_raise(EventTable::build(lcm_path_));
    return events_;
  }

  static py::dict to_dict(Channel ch) {
    const size_t n = ch.arrival.size();
    py::dict out;
    py::object stamp;
    for (Column& c : ch.columns) {
      std::string name = c.name;
      py::object a = column_array(std::move(c), n);
      if (name == "header.utime") stamp = a;
      out[py::str(name)] = a;
    }
    out["stamp"] = stamp ? stamp : py::object(py::none());
    out["arrival"] = adopt(std::move(ch.arrival), py::dtype::of<int64_t>(), {static_cast<py::ssize_t>(n)});
    return out;
  }

  std::vector<std::string> inputs_;
  std::string lcm_path_;
  std::shared_ptr<LogIndex> index_;
  mutable std::mutex events_mutex_;
  mutable std::shared_ptr<const EventTable> events_;
};

/// `driftlab diagnose --json`'s JSON text for inputs.
std::string diagnose_json(const std::vector<std::string>& inputs, double max_lag_s, double window_s,
                          const std::string& channels) {
  for (const auto& [option, value, range] :
       {std::tuple{"--max-lag", max_lag_s, apps::kMaxLagRange}, {"--window", window_s, apps::kWindowRange}}) {
    if (std::string why = range.violation(value, "s"); !why.empty()) {
      throw DriftlabError(std::string(option) + ": " + why + ", got " + short_number(value));
    }
  }
  py::gil_scoped_release release;
  const std::string log = value_or_raise(recordings::event_log_for(inputs));
  analyzers::DiagnoseOptions options;
  options.max_lag_s = max_lag_s;
  options.window_s = window_s;
  options.channels = channels;
  return analyzers::diagnose_json(value_or_raise(analyzers::run_diagnosis(log, options))).dump(2) + "\n";
}

/// A command of `driftlab` run in-process with these arguments (after "driftlab"), `--json` among them: what it
/// printed as JSON. Its error, or a usage error, as DriftlabError with the command's message.
std::string run_command(const std::vector<std::string>& args) {
  py::gil_scoped_release release;
  CLI::App app{"driftlab", "driftlab"};
  app.require_subcommand(1);
  int exit_code = apps::kExitOk;
  apps::add_eval_command(app, &exit_code);
  std::vector<std::string> argv = {"driftlab"};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> c;
  c.reserve(argv.size());
  for (auto& a : argv) c.push_back(a.data());
  apps::OutputCapture capture;
  try {
    app.parse(static_cast<int>(c.size()), c.data());
  } catch (const CLI::ParseError& e) {
    throw DriftlabError(std::string(e.what()));
  }
  if (exit_code != apps::kExitOk) {
    throw DriftlabError(capture.error.empty() ? "failed with exit code " + std::to_string(exit_code) : capture.error);
  }
  return capture.text;
}

py::dict import_log(const std::vector<std::string>& inputs, const std::string& out) {
  formats::ImportSummary s;
  std::vector<std::string> problems;
  {
    py::gil_scoped_release release;
    if (Status st = refuse_same_file(out, inputs); !st) throw DriftlabError(st.message());
    if (inputs.size() == 1 && formats::detect_format(inputs[0]).format == formats::Format::kMrptRawlog) {
      throw DriftlabError(inputs[0] + ": an MRPT rawlog: convert it with 'driftlab import rawlog'");
    }
    s = value_or_raise(formats::import_log(inputs, out, [&](const std::string& line) { problems.push_back(line); }));
  }
  py::dict d;
  d["format"] = s.format;
  d["messages"] = s.messages;
  py::list topics;
  for (const auto& t : s.topics) {
    py::dict x;
    x["channel"] = t.channel;
    x["source_type"] = t.source_type;
    x["driftlab_type"] = t.driftlab_type;
    x["messages"] = t.messages;
    x["malformed"] = t.malformed;
    topics.append(x);
  }
  d["topics"] = topics;
  py::dict skipped;
  for (const auto& [name, n] : s.skipped) skipped[py::str(name)] = n;
  d["skipped"] = skipped;
  d["problems"] = problems;
  d["out"] = out;
  return d;
}

}  // namespace
}  // namespace driftlab::python

PYBIND11_MODULE(_driftlab, m) {
  using namespace driftlab::python;
  m.doc() = "driftlab's C++ core (use the driftlab package)";
  // driftlab.Error: both a RuntimeError and a ValueError (bad input is most of what it reports).
  py::register_exception<DriftlabError>(
      m, "Error", py::make_tuple(py::handle(PyExc_RuntimeError), py::handle(PyExc_ValueError)).release());
  py::class_<Log>(m, "Log")
      .def(py::init<std::vector<std::string>>(), py::arg("inputs"))
      .def_property_readonly("path", &Log::path)
      .def_property_readonly("lcm_path", &Log::lcm_path)
      .def_property_readonly("channels", &Log::channels)
      .def("info", &Log::info)
      .def("read", &Log::read, py::arg("channel"))
      .def("read_many", &Log::read_many, py::arg("channels") = py::none(), py::arg("threads") = 0)
      .def("_read_reference", &Log::read_reference, py::arg("channels") = py::none());
  m.def("diagnose_json", &diagnose_json, py::arg("inputs"), py::arg("max_lag_s"), py::arg("window_s"),
        py::arg("channels"));
  m.def("run_command", &run_command, py::arg("args"));
  m.def("import_log", &import_log, py::arg("inputs"), py::arg("out"));
}
