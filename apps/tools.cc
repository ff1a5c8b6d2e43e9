// The dispatch from `driftlab` to the programs that hold the heavy commands, and what every driftlab program shares
// around CLI11.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/install_layout.h"

namespace driftlab::apps {
namespace {

constexpr std::array<ToolCommand, 5> kTools = {{
    {"sim", nullptr, "driftlab-sim",
     "Simulate a robot (Bullet world, URDF robot, sensors, faults) and write every stream to an LCM log."},
    {"replay", nullptr, "driftlab-replay",
     "Replay logs through SLAM, the estimator and the controller on a virtual clock, deterministically."},
    {"run", nullptr, "driftlab-replay", "Run SLAM, the estimator and the controller live, on an LCM bus."},
    {"import", "rawlog", "driftlab-rawlog", "An MRPT rawlog (either format, plain or gzip) to a driftlab log."},
    {"export", "rawlog", "driftlab-rawlog", "A driftlab log to an MRPT rawlog (observations only)."},
}};

}  // namespace

std::span<const ToolCommand> tool_commands() { return kTools; }

const char* tool_description(const char* word, const char* sub) {
  for (const auto& t : kTools) {
    if (std::strcmp(t.word, word) == 0 && (t.sub == nullptr) == (sub == nullptr) &&
        (sub == nullptr || std::strcmp(t.sub, sub) == 0)) {
      return t.description;
    }
  }
  return "";
}

const ToolCommand* find_tool(int argc, char** argv) {
  if (argc < 2) return nullptr;
  for (const auto& t : kTools) {
    if (std::strcmp(argv[1], t.word) != 0) continue;
    if (t.sub == nullptr || (argc > 2 && std::strcmp(argv[2], t.sub) == 0)) return &t;
  }
  return nullptr;
}

int exec_tool(const ToolCommand& tool, char** argv) {
  const std::string found = sibling_program(tool.program).string();
  if (!found.empty()) {
    argv[0] = const_cast<char*>(found.c_str());
    ::execv(found.c_str(), argv);
    return fail(found + ": cannot run: " + std::strerror(errno), kExitFailure);
  }
  argv[0] = const_cast<char*>(tool.program);
  ::execvp(tool.program, argv);
  return fail(std::string(tool.program) + " (which runs 'driftlab " + tool.word +
                  "') is neither beside driftlab, nor in its lib/driftlab, nor on PATH: " + std::strerror(errno),
              kExitFailure);
}

namespace {

bool has_range(CLI::Option& opt) {
  try {
    return opt.get_validator(kRangeCheck) != nullptr;
  } catch (const CLI::OptionNotFound&) {
    return false;
  }
}

/// Checks what CLI11's own conversions let through: NaN, infinities and overflowing numbers ("1e309") for
/// floating options, and integers beyond their type (which CLI11 2.1 clamps silently). A number option without a
/// range (apps/cli_checks.h) is a bug: it aborts, so that every command's --help (which a test runs) shows it.
void harden(CLI::App& app) {
  for (CLI::Option* opt : app.get_options()) {
    if (opt->get_type_size() == 0) continue;  // a flag
    const std::string full = opt->get_type_name();  // "FLOAT", or "FLOAT:[0, 60]" with validators
    const std::string type = full.substr(0, full.find(':'));
    if ((type == "FLOAT" || type == "INT" || type == "UINT") && !has_range(*opt)) {
      std::fprintf(stderr, "driftlab: internal error: option %s of '%s' has no range (apps/cli_checks.h)\n",
                   opt->get_name().c_str(), app.get_name().c_str());
      std::abort();
    }
    if (type == "FLOAT") {
      opt->check(CLI::Validator(
          [](std::string& v) -> std::string {
            char* end = nullptr;
            errno = 0;
            const double d = std::strtod(v.c_str(), &end);
            if (end == v.c_str() || *end != '\0') return "";  // not a number: CLI11's conversion says so
            if (!std::isfinite(d) || errno == ERANGE) return "must be a finite number, got " + v;
            return "";
          },
          ""));
    } else if (type == "INT" || type == "UINT") {
      const bool is_unsigned = type == "UINT";
      opt->check(CLI::Validator(
          [is_unsigned](std::string& v) -> std::string {
            const char* begin = v.c_str();
            const char* end = begin + v.size();
            std::from_chars_result r{};
            if (is_unsigned) {
              uint64_t x = 0;
              r = std::from_chars(begin, end, x);
            } else {
              int64_t x = 0;
              r = std::from_chars(begin, end, x);
            }
            if (r.ec == std::errc::result_out_of_range) return "is out of range: " + v;
            return "";
          },
          ""));
    }
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) harden(*sub);
}

}  // namespace

int parse_and_run(CLI::App& app, int argc, char** argv, const int& exit_code) {
  // A file-size limit (ulimit -f) then shows as a write error (EFBIG), like a full disk, so every command cleans
  // up its partial outputs and says so, instead of being killed by SIGXFSZ halfway through a write.
  std::signal(SIGXFSZ, SIG_IGN);
  harden(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::Success& e) {  // --help-config
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line naming the problem, then where to look; exit 2 like other usage errors.
    return fail(std::string(e.what()) + " (see 'driftlab --help')");
  }
  return exit_code;
}

void add_config_help(CLI::App& cmd, void (*print)()) {
  cmd.add_flag_callback(
      "--help-config",
      [print] {
        print();
        throw CLI::Success();
      },
      "Print the keys of the config files this command reads (type, unit, default, range) and exit");
}

CLI::App& add_import_command(CLI::App& app) {
  CLI::App* import = app.add_subcommand("import", "Convert another format into a driftlab log.");
  import->require_subcommand(1);
  return *import;
}

CLI::App& add_export_command(CLI::App& app) {
  CLI::App* exp = app.add_subcommand("export", "Convert a driftlab log into another format.");
  exp->require_subcommand(1);
  return *exp;
}

}  // namespace driftlab::apps
