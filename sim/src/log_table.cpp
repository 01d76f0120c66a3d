// The simulation log's columns (log_table.hpp).
#include "virtmech/sim/log_table.hpp"

#include <sstream>

namespace virtmech::sim {

const std::vector<LogField>& log_fields() {
#define VM_LOG_ROW(field, width, names, units, origin) \
  {#field, kLogWidth##width, names, units, VM_LOG_DERIVED_##origin},
#define VM_LOG_DERIVED_LOOP false
#define VM_LOG_DERIVED_DERIVED true
  static const std::vector<LogField> rows = {VM_LOG_TABLE(VM_LOG_ROW)};
#undef VM_LOG_ROW
#undef VM_LOG_DERIVED_LOOP
#undef VM_LOG_DERIVED_DERIVED
  return rows;
}

int log_width(const LogField& f, int n, int m) {
  return f.width == kLogWidthN ? n : f.width == kLogWidthM ? m : f.width;
}

std::vector<std::string> log_names(const LogField& f, int n, int m) {
  std::vector<std::string> words;
  std::istringstream in(f.names);
  for (std::string w; in >> w;) words.push_back(w);
  const int width = log_width(f, n, m);
  const bool per_joint = f.width == kLogWidthN || f.width == kLogWidthM;
  if (!per_joint && static_cast<int>(words.size()) == width) return words;
  std::vector<std::string> out;  // a prefix: prefix0, prefix1, ...
  for (int i = 0; i < width; ++i) out.push_back(words.front() + std::to_string(i));
  return out;
}

std::vector<std::string> log_column_names(int n, int m) {
  std::vector<std::string> out;
  for (const LogField& f : log_fields()) {
    const std::vector<std::string> names = log_names(f, n, m);
    out.insert(out.end(), names.begin(), names.end());
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> log_units(const LogField& f) {
  const std::string units = f.units;
  if (units.empty()) return {};
  if (units.find('=') == std::string::npos) {
    std::istringstream in(f.names);
    std::string first;
    in >> first;
    return {{first, units}};
  }
  std::vector<std::pair<std::string, std::string>> out;
  std::istringstream in(units);
  for (std::string item; std::getline(in, item, '|');) {
    const size_t eq = item.find('=');
    out.emplace_back(item.substr(0, eq), item.substr(eq + 1));
  }
  return out;
}

}  // namespace virtmech::sim
