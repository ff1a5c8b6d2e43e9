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
#include "core/check.h"
#include "core/closest_name.h"
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
      const std::string why =
          "option " + opt->get_name() + " of '" + app.get_name() + "' has no range (apps/cli_checks.h)";
      internal_error(__FILE__, __LINE__, why.c_str());
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

/// The command the words of argv reached: `driftlab export mcap` for "driftlab export mcap x.lcm --jsno".
CLI::App* deepest_command(CLI::App& app) {
  CLI::App* at = &app;
  for (;;) {
    auto parsed = at->get_subcommands();
    if (parsed.empty()) return at;
    at = parsed.back();
  }
}

std::string command_path(const CLI::App& cmd) {
  std::string path = cmd.get_name();
  for (const CLI::App* p = cmd.get_parent(); p != nullptr; p = p->get_parent()) path = p->get_name() + " " + path;
  return path;
}

/// The names a word could have meant at cmd: its subcommands' names, or its options' long and short names.
std::vector<std::string> names_at(CLI::App& cmd, bool options) {
  std::vector<std::string> names;
  if (options) {
    for (const CLI::Option* opt : cmd.get_options()) {
      for (const auto& n : opt->get_lnames()) names.push_back("--" + n);
      for (const auto& n : opt->get_snames()) names.push_back("-" + n);
    }
  } else {
    for (const CLI::App* sub : cmd.get_subcommands([](CLI::App*) { return true; })) names.push_back(sub->get_name());
  }
  return names;
}

/// The words of argv that cmd did not take (unknown options and surplus arguments), or, when it wants a
/// subcommand and got none, the word after its own name (*command set).
std::vector<std::string> unknown_words(CLI::App& cmd, int argc, char** argv, bool* command) {
  *command = cmd.get_require_subcommand_min() > 0 && cmd.get_subcommands().empty();
  if (!*command) return cmd.remaining();
  // argv[0] is the program; the first word after the command's own name (or the program's) is the one meant.
  int i = 1;
  if (cmd.get_parent() != nullptr) {
    while (i < argc && cmd.get_name() != argv[i]) ++i;
    ++i;
  }
  for (; i < argc; ++i) {
    if (argv[i][0] != '-') return {argv[i]};
  }
  return {};
}

/// CLI11's message for a usage error, with a guess at a mistyped command or option ("did you mean 'diagnose'?")
/// and the --help of the command it was given to.
std::string usage_error_line(CLI::App& app, const std::string& what, int argc, char** argv) {
  CLI::App* cmd = deepest_command(app);
  const std::string path = command_path(*cmd);
  bool command = false;
  const auto words = unknown_words(*cmd, argc, argv, &command);
  // CLI11's "A subcommand is required" and "The following argument was not expected: --jsno" said plainly.
  std::string line = what;
  if (command && !words.empty()) {
    line = "'" + words.front() + "' is not a command of '" + path + "'";
  } else if (!words.empty() && words.front()[0] == '-') {
    const std::string unknown = "unknown option '" + words.front() + "'";
    line = what.find("not expected") != std::string::npos ? unknown : what + "; " + unknown;
  }
  if (!words.empty()) {
    const bool option = words.front()[0] == '-';
    const std::string& word = words.front();
    const std::string guess = closest_name(option ? word.substr(0, word.find('=')) : word, names_at(*cmd, option));
    if (!guess.empty()) line += ": did you mean '" + guess + "'?";
  }
  return line + " (see '" + path + " --help')";
}

}  // namespace

int parse_and_run(CLI::App& app, int argc, char** argv, const int& exit_code) {
  // A file-size limit (ulimit -f) then shows as a write error (EFBIG), like a full disk, so every command cleans
  // up its partial outputs and says so, instead of being killed by SIGXFSZ halfway through a write.
  std::signal(SIGXFSZ, SIG_IGN);
  harden(app);
  // `--json FILE` was the way to write a diagnosis or evaluation to a file; --json now prints and takes no value,
  // so the file would be read as an input. Said plainly rather than "FILE: no such file".
  for (int i = 1; i + 1 < argc; ++i) {
    const std::string_view next = argv[i + 1];
    if (std::string_view(argv[i]) == "--json" &&
        (next == "-" || (next.size() > 5 && next.substr(next.size() - 5) == ".json"))) {
      return fail("--json takes no file: it prints the JSON; --json-out " + std::string(next) + " writes it");
    }
  }
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
    // One line naming the problem, a guess at what was meant, and the --help of the command it was given to; exit
    // 2 like other usage errors.
    return fail(usage_error_line(app, e.what(), argc, argv));
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
