#include "usage.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "rt/render/ray_offset.h"

namespace rt {

namespace {

// Optimal string alignment distance (Levenshtein with swaps of adjacent characters).
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitution = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + substitution});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

std::vector<std::string> command_names(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::App* command : app.get_subcommands([](const CLI::App*) { return true; }))
    names.push_back(command->get_name());
  return names;
}

// Every spelling of every flag `command` accepts (--name and -n), its parents' included (--help).
std::vector<std::string> flag_names(const CLI::App& command) {
  std::vector<std::string> names;
  for (const CLI::App* app = &command; app != nullptr; app = app->get_parent())
    for (const CLI::Option* option : app->get_options()) {
      for (const std::string& name : option->get_lnames()) names.push_back("--" + name);
      for (const std::string& name : option->get_snames()) names.push_back("-" + name);
    }
  return names;
}

std::string spoken_list(const std::vector<std::string>& names) {
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i)
    text += (i == 0 ? "" : i + 1 == names.size() ? " and " : ", ") + names[i];
  return text;
}

// "--eye: 3 required X Y Z:FINITE missing" -> "--eye takes 3 values (X Y Z)".
std::string reword_mismatch(const CLI::App& command, const std::string& message) {
  const std::size_t colon = message.find(": ");
  if (colon == std::string::npos || !message.starts_with("-")) return message;
  const std::string flag = message.substr(0, colon);
  int count = 0;
  if (std::sscanf(message.c_str() + colon + 2, "%d required", &count) != 1) return message;
  std::string type;
  try {
    type = command.get_option(flag)->get_type_name();
  } catch (const CLI::OptionNotFound&) {
    return message;
  }
  type = type.substr(0, type.find(':'));
  return fmt::format("{} takes {} value{}{}", flag, count, count == 1 ? "" : "s", type.empty() ? "" : " (" + type + ")");
}

}  // namespace

CLI::Validator whole_number_in(long long lo, long long hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long long value = std::strtoll(text.c_str(), &end, 10);
        const bool digits = !text.empty() && text.find_first_of(" \t\n") == std::string::npos;
        if (!digits || end != text.c_str() + text.size()) return fmt::format("'{}' is not a whole number", text);
        if (errno == ERANGE || value < lo || value > hi) return fmt::format("{} is outside {}..{}", text, lo, hi);
        return "";
      },
      fmt::format("{}..{}", lo, hi));
}

CLI::Validator number_in(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value))
          return fmt::format("'{}' is not a finite number", text);
        if (value < lo || value > hi) return fmt::format("{} is outside [{}, {}]", text, lo, hi);
        return "";
      },
      fmt::format("[{}, {}]", lo, hi));
}

const CLI::Validator kRayOffset(
    [](std::string& text) -> std::string {
      try {
        parse_ray_offset(text);
        return "";
      } catch (const std::exception&) {
        return fmt::format("'{}' is neither robust nor fixed:EPS with a finite EPS > 0 (e.g. fixed:1e-4)", text);
      }
    },
    "robust|fixed:EPS");

CLI::Validator one_of(const std::vector<std::string>& values) {
  return CLI::Validator(
      [values](std::string& text) -> std::string {
        if (std::find(values.begin(), values.end(), text) != values.end()) return "";
        const std::string near = nearest_name(text, values);
        return fmt::format("'{}' is not one of {}{}", text, fmt::join(values, ", "),
                           near.empty() ? "" : " (did you mean " + near + "?)");
      },
      fmt::format("{}", fmt::join(values, "|")));
}

std::string nearest_name(const std::string& typed, const std::vector<std::string>& names) {
  std::string best;
  std::size_t best_distance = std::string::npos;
  for (const std::string& name : names)
    if (const std::size_t distance = edit_distance(typed, name); distance < best_distance) {
      best = name;
      best_distance = distance;
    }
  const std::size_t length = std::max(typed.size(), best.size());
  const std::size_t allowed = length <= 4 ? 1 : std::min<std::size_t>(2, (length - 1) / 2);
  return best_distance <= allowed ? best : std::string();
}

std::string usage_message(const CLI::App& app, const CLI::ParseError& error, int argc, const char* const* argv) {
  const std::vector<std::string> commands = command_names(app);
  const std::vector<CLI::App*> chosen = app.get_subcommands();
  if (chosen.empty()) {
    const std::string what = fmt::format("the commands are {} (rt --help)", spoken_list(commands));
    if (argc < 2) return "no command given: " + what;
    const std::string first = argv[1];
    if (!first.starts_with("-")) {
      const std::string near = nearest_name(first, commands);
      return fmt::format("unknown command '{}'{}; {}", first, near.empty() ? "" : " (did you mean '" + near + "'?)", what);
    }
  }
  // Extras left at the top level were given before the command.
  const bool top_level = chosen.empty() || !app.remaining(false).empty();
  const CLI::App& command = top_level ? app : *chosen.front();
  const std::string invocation = top_level ? "rt" : "rt " + command.get_name();
  const std::string help = fmt::format(" ({} --help lists the options)", invocation);

  // CLI11 reports a missing command before unknown flags: "rt --verison" is the unknown flag.
  if (dynamic_cast<const CLI::ExtrasError*>(&error) != nullptr || (chosen.empty() && !app.remaining(false).empty())) {
    // A flag of a command given before the command ("rt --spp 4 render") is left over at the top.
    for (const std::string& extra : app.remaining(false))
      for (const std::string& name : commands)
        if (const std::vector<std::string> flags = flag_names(*app.get_subcommand(name));
            std::find(flags.begin(), flags.end(), extra.substr(0, extra.find('='))) != flags.end())
          return fmt::format("{} is an option of rt {}: put it after the command (rt {} ... {} ...)",
                             extra.substr(0, extra.find('=')), name, name, extra);
    for (const std::string& extra : app.remaining(true)) {
      if (!extra.starts_with("-") || extra == "-")
        return fmt::format("unexpected argument '{}' for {}{}", extra, invocation, help);
      const std::string flag = extra.substr(0, extra.find('='));
      // One-letter flags are too short to guess from.
      const std::string near = flag.size() > 2 ? nearest_name(flag, flag_names(command)) : "";
      return fmt::format("unknown option {} for {}{}{}", flag, invocation,
                         near.empty() ? "" : " (did you mean " + near + "?)", near.empty() ? help : "");
    }
  }
  std::string message = error.what();
  if (dynamic_cast<const CLI::ArgumentMismatch*>(&error) != nullptr) message = reword_mismatch(command, message);
  return message + help;
}

}  // namespace rt
