#include "rt/core/error.h"

namespace rt {

namespace {
std::string format_input_error(const std::string& file, const std::string& where, const std::string& reason) {
  std::string message = file;
  if (!where.empty()) message += ":" + where;
  return message + ": " + reason;
}
}  // namespace

InputError::InputError(const std::string& file, const std::string& where, const std::string& reason)
    : std::runtime_error(format_input_error(file, where, reason)) {}

}  // namespace rt
