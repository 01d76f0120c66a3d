// The stand-in vendor libraries' configuration (standin_hd.cpp, standin_dhd.cpp): the file
// named by the environment variable VIRTMECH_STANDIN_CONFIG, one "key value..." per line
// ('#' starts a comment).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace standin_config {

class Config {
 public:
  void load() {
    const char* path = std::getenv("VIRTMECH_STANDIN_CONFIG");
    if (path == nullptr || path[0] == '\0') return;
    std::ifstream in(path);
    if (!in) {
      std::fprintf(stderr, "stand-in: cannot read %s\n", path);
      return;
    }
    std::string line;
    while (std::getline(in, line)) {
      const auto hash = line.find('#');
      if (hash != std::string::npos) line.erase(hash);
      std::istringstream words(line);
      std::string key;
      if (!(words >> key)) continue;
      std::vector<std::string> values;
      for (std::string v; words >> v;) values.push_back(v);
      values_[key] = values;
    }
  }
  bool has(const std::string& key) const { return values_.count(key) > 0; }
  std::string text(const std::string& key, const std::string& fallback) const {
    auto it = values_.find(key);
    if (it == values_.end() || it->second.empty()) return fallback;
    std::string out;
    for (const auto& w : it->second) out += (out.empty() ? "" : " ") + w;
    return out;
  }
  double number(const std::string& key, double fallback, size_t i = 0) const {
    auto it = values_.find(key);
    if (it == values_.end() || it->second.size() <= i) return fallback;
    return std::strtod(it->second[i].c_str(), nullptr);
  }
  long integer(const std::string& key, long fallback, size_t i = 0) const {
    auto it = values_.find(key);
    if (it == values_.end() || it->second.size() <= i) return fallback;
    return std::strtol(it->second[i].c_str(), nullptr, 0);
  }
  std::vector<double> numbers(const std::string& key) const {
    std::vector<double> out;
    auto it = values_.find(key);
    if (it != values_.end()) {
      for (const auto& w : it->second) out.push_back(std::strtod(w.c_str(), nullptr));
    }
    return out;
  }
  std::vector<std::string> words(const std::string& key) const {
    auto it = values_.find(key);
    return it == values_.end() ? std::vector<std::string>{} : it->second;
  }

 private:
  std::map<std::string, std::vector<std::string>> values_;
};

/// `count` float64 values of the file at `path` (fewer where it is shorter; none, with a
/// message naming `who`, where it cannot be read).
inline std::vector<double> read_doubles(const std::string& path, size_t count, const char* who) {
  std::vector<double> out(count, 0.0);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    std::fprintf(stderr, "%s: cannot read %s\n", who, path.c_str());
    return {};
  }
  const size_t got = std::fread(out.data(), sizeof(double), count, f);
  std::fclose(f);
  out.resize(got);
  return out;
}

}  // namespace standin_config
