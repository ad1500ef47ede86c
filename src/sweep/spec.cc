#include "superdyna/sweep/spec.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdlib>
#include <set>

#include "superdyna/core/error.h"
#include "superdyna/io/yaml_file.h"
#include "superdyna/sweep/tables.h"

namespace superdyna::sweep {

namespace fs = std::filesystem;

namespace {

const std::set<std::string> kModes = {"mono", "stereo", "mono-inertial", "stereo-inertial"};
const std::set<std::string> kFormats = {"auto", "tum", "euroc", "kitti"};

/// Reads one spec file; every error names the file, the line and the field.
class SpecReader {
 public:
  explicit SpecReader(const fs::path& file)
      : yaml_(io::YamlFile::load(file)), dir_(fs::absolute(file).parent_path()) {}

  SweepSpec read() {
    SweepSpec spec;
    spec.file = fs::absolute(yaml_.path());
    const YAML::Node& root = yaml_.root();
    if (!root.IsMap()) throw InputError(yaml_.at(root, ""), "a sweep spec is a YAML map");
    checkKeys(root, "", {"name", "runs", "eval", "sequences", "configs", "tables"});
    spec.name = root["name"] ? text(root["name"], "name") : yaml_.path().stem().string();
    if (root["runs"]) spec.runs = positiveInt(root["runs"], "runs");
    if (root["eval"]) spec.eval = readEval(root["eval"]);
    for (const YAML::Node& node : list(yaml_.child("sequences"), "sequences")) {
      spec.sequences.push_back(readSequence(node, spec.sequences.size()));
    }
    for (const YAML::Node& node : list(yaml_.child("configs"), "configs")) {
      spec.configs.push_back(readConfig(node, spec.configs.size()));
    }
    if (root["tables"]) {
      for (const YAML::Node& node : list(root["tables"], "tables")) {
        spec.tables.push_back(readTable(node, spec.tables.size()));
      }
    }
    checkNames(spec);
    return spec;
  }

 private:
  std::vector<YAML::Node> list(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence() || node.size() == 0) {
      throw InputError(yaml_.at(node, field), "expected a non-empty list");
    }
    return {node.begin(), node.end()};
  }

  void checkKeys(const YAML::Node& map, const std::string& field,
                 const std::set<std::string>& known) const {
    if (!map.IsMap()) throw InputError(yaml_.at(map, field), "expected a map");
    for (const auto& entry : map) {
      const std::string key = entry.first.as<std::string>();
      if (!known.count(key)) {
        throw InputError(yaml_.at(entry.first, field.empty() ? key : field + "." + key),
                         fmt::format("unknown field (known: {})", fmt::join(known, ", ")));
      }
    }
  }

  std::string text(const YAML::Node& node, const std::string& field) const {
    return expandEnvironment(yaml_.scalar(node, field), yaml_.at(node, field).describe());
  }

  std::vector<std::string> texts(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence()) throw InputError(yaml_.at(node, field), "expected a list");
    std::vector<std::string> values;
    for (std::size_t i = 0; i < node.size(); ++i) {
      values.push_back(text(node[i], fmt::format("{}[{}]", field, i)));
    }
    return values;
  }

  int positiveInt(const YAML::Node& node, const std::string& field) const {
    const double value = yaml_.number(node, field);
    if (value < 1 || value > 1000 || value != static_cast<int>(value)) {
      throw InputError(yaml_.at(node, field), "expected a whole number from 1 to 1000");
    }
    return static_cast<int>(value);
  }

  std::string oneOf(const YAML::Node& node, const std::string& field,
                    const std::set<std::string>& allowed) const {
    const std::string value = text(node, field);
    if (!allowed.count(value)) {
      throw InputError(yaml_.at(node, field),
                       fmt::format("'{}' is not one of {}", value, fmt::join(allowed, ", ")));
    }
    return value;
  }

  fs::path existing(const fs::path& base, const YAML::Node& node, const std::string& field) const {
    const fs::path path = base / text(node, field);
    if (!fs::exists(path)) {
      throw InputError(yaml_.at(node, field), fmt::format("'{}' does not exist", path.string()));
    }
    return fs::weakly_canonical(path);
  }

  EvalSpec readEval(const YAML::Node& node) const {
    checkKeys(node, "eval", {"max_diff", "rpe_delta", "rpe_unit"});
    EvalSpec eval;
    if (node["max_diff"]) eval.max_diff_s = yaml_.number(node["max_diff"], "eval.max_diff");
    if (node["rpe_delta"]) eval.rpe_delta = yaml_.number(node["rpe_delta"], "eval.rpe_delta");
    if (node["rpe_unit"]) eval.rpe_unit = oneOf(node["rpe_unit"], "eval.rpe_unit", {"m", "frames"});
    if (eval.max_diff_s <= 0 || eval.rpe_delta <= 0) {
      throw InputError(yaml_.at(node, "eval"), "max_diff and rpe_delta must be positive");
    }
    return eval;
  }

  SequenceSpec readSequence(const YAML::Node& node, std::size_t index) const {
    const std::string at = fmt::format("sequences[{}]", index);
    checkKeys(node, at,
              {"name", "simulate", "dataset", "path", "run_args", "ground_truth",
               "ground_truth_format", "ground_truth_times"});
    SequenceSpec s;
    s.name = text(yaml_.child(node, "name", at + ".name"), at + ".name");
    if (node["simulate"]) s.simulate_args = texts(node["simulate"], at + ".simulate");
    if (node["simulate"] && s.simulate_args.empty()) {
      throw InputError(yaml_.at(node["simulate"], at + ".simulate"), "no simulator arguments");
    }
    if (node["simulate"] && node["path"]) {
      throw InputError(yaml_.at(node["path"], at + ".path"),
                       "a sequence is either simulated or read from a path, not both");
    }
    if (!node["simulate"])
      s.path = existing(dir_, yaml_.child(node, "path", at + ".path"), at + ".path");
    if (node["dataset"]) s.dataset = text(node["dataset"], at + ".dataset");
    if (node["run_args"]) s.run_args = texts(node["run_args"], at + ".run_args");
    if (node["ground_truth"]) s.ground_truth = text(node["ground_truth"], at + ".ground_truth");
    if (node["ground_truth_format"]) {
      s.ground_truth_format =
          oneOf(node["ground_truth_format"], at + ".ground_truth_format", kFormats);
    }
    if (node["ground_truth_times"]) {
      s.ground_truth_times = text(node["ground_truth_times"], at + ".ground_truth_times");
    }
    return s;
  }

  ConfigSpec readConfig(const YAML::Node& node, std::size_t index) const {
    const std::string at = fmt::format("configs[{}]", index);
    checkKeys(node, at,
              {"name", "mode", "config", "set", "args", "deterministic", "runs", "align",
               "sequences", "command", "trajectory", "trajectory_format", "time_unit"});
    ConfigSpec c;
    c.name = text(yaml_.child(node, "name", at + ".name"), at + ".name");
    if (node["mode"]) c.mode = oneOf(node["mode"], at + ".mode", kModes);
    if (node["config"]) c.config = existing(dir_, node["config"], at + ".config");
    if (node["set"]) {
      checkMap(node["set"], at + ".set");
      for (const auto& entry : node["set"]) {
        const std::string key = entry.first.as<std::string>();
        c.set[key] = text(entry.second, at + ".set." + key);
      }
    }
    if (node["args"]) c.args = texts(node["args"], at + ".args");
    if (node["deterministic"])
      c.deterministic = boolean(node["deterministic"], at + ".deterministic");
    if (node["runs"]) c.runs = positiveInt(node["runs"], at + ".runs");
    if (node["align"]) c.align = oneOf(node["align"], at + ".align", {"none", "se3", "sim3"});
    if (node["sequences"]) c.sequences = texts(node["sequences"], at + ".sequences");
    if (node["command"]) c.command = text(node["command"], at + ".command");
    if (node["trajectory"]) c.trajectory = text(node["trajectory"], at + ".trajectory");
    if (node["trajectory_format"]) {
      c.trajectory_format = oneOf(node["trajectory_format"], at + ".trajectory_format", kFormats);
    }
    if (node["time_unit"]) c.time_unit = oneOf(node["time_unit"], at + ".time_unit", {"s", "ns"});
    if (c.external() && (node["config"] || node["set"] || node["args"])) {
      throw InputError(yaml_.at(node, at),
                       "an external command takes no config, set or args: put them in the command");
    }
    return c;
  }

  TableSpec readTable(const YAML::Node& node, std::size_t index) const {
    const std::string at = fmt::format("tables[{}]", index);
    checkKeys(node, at, {"name", "title", "metric", "rows", "configs", "sequences"});
    TableSpec t;
    t.name = text(yaml_.child(node, "name", at + ".name"), at + ".name");
    t.title = node["title"] ? text(node["title"], at + ".title") : t.name;
    if (node["metric"]) {
      std::set<std::string> metrics;
      for (const Metric& m : metrics_())
        metrics.insert(m.name);
      t.metric = oneOf(node["metric"], at + ".metric", metrics);
    }
    if (node["rows"]) {
      t.rows_are_configs = oneOf(node["rows"], at + ".rows", {"sequences", "configs"}) == "configs";
    }
    if (node["configs"]) t.configs = texts(node["configs"], at + ".configs");
    if (node["sequences"]) t.sequences = texts(node["sequences"], at + ".sequences");
    return t;
  }

  static const std::vector<Metric>& metrics_() { return metrics(); }

  void checkMap(const YAML::Node& node, const std::string& field) const {
    if (!node.IsMap()) throw InputError(yaml_.at(node, field), "expected a map");
  }

  bool boolean(const YAML::Node& node, const std::string& field) const {
    const std::string value = yaml_.scalar(node, field);
    if (value == "true" || value == "yes" || value == "on") return true;
    if (value == "false" || value == "no" || value == "off") return false;
    throw InputError(yaml_.at(node, field), fmt::format("'{}' is not true or false", value));
  }

  void checkNames(const SweepSpec& spec) const {
    std::set<std::string> sequences, configs;
    const auto checkName = [&](const std::string& name, const std::string& kind) {
      const bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char ch) {
        return std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_' || ch == '.';
      });
      if (!ok || name == "." || name == "..") {
        throw InputError(yaml_.at(yaml_.root(), kind),
                         fmt::format("'{}' is not a usable name (letters, digits, - _ . only: it "
                                     "names a folder)",
                                     name));
      }
    };
    for (const SequenceSpec& s : spec.sequences) {
      checkName(s.name, "sequences");
      if (!sequences.insert(s.name).second) {
        throw InputError(yaml_.at(yaml_.root(), "sequences"),
                         fmt::format("two sequences are named '{}'", s.name));
      }
    }
    for (const ConfigSpec& c : spec.configs) {
      checkName(c.name, "configs");
      if (!configs.insert(c.name).second) {
        throw InputError(yaml_.at(yaml_.root(), "configs"),
                         fmt::format("two configs are named '{}'", c.name));
      }
      for (const std::string& s : c.sequences) {
        if (!sequences.count(s)) {
          throw InputError(yaml_.at(yaml_.root(), "configs"),
                           fmt::format("config '{}' names an unknown sequence '{}'", c.name, s));
        }
      }
    }
    for (const TableSpec& t : spec.tables) {
      for (const std::string& c : t.configs) {
        if (!configs.count(c)) {
          throw InputError(yaml_.at(yaml_.root(), "tables"),
                           fmt::format("table '{}' names an unknown config '{}'", t.name, c));
        }
      }
      for (const std::string& s : t.sequences) {
        if (!sequences.count(s)) {
          throw InputError(yaml_.at(yaml_.root(), "tables"),
                           fmt::format("table '{}' names an unknown sequence '{}'", t.name, s));
        }
      }
    }
  }

  io::YamlFile yaml_;
  fs::path dir_;
};

}  // namespace

bool ConfigSpec::runsOn(const std::string& sequence) const {
  return sequences.empty() ||
         std::find(sequences.begin(), sequences.end(), sequence) != sequences.end();
}

std::string ConfigSpec::alignment() const {
  if (!align.empty()) return align;
  return mode == "mono" ? "sim3" : "se3";
}

const SequenceSpec& SweepSpec::sequence(const std::string& wanted) const {
  for (const SequenceSpec& s : sequences) {
    if (s.name == wanted) return s;
  }
  throw InputError(InputLocation(file, 0, "sequences"), fmt::format("no sequence '{}'", wanted));
}

const ConfigSpec& SweepSpec::config(const std::string& wanted) const {
  for (const ConfigSpec& c : configs) {
    if (c.name == wanted) return c;
  }
  throw InputError(InputLocation(file, 0, "configs"), fmt::format("no config '{}'", wanted));
}

SweepSpec loadSweepSpec(const fs::path& file) {
  return SpecReader(file).read();
}

std::string expandEnvironment(const std::string& text, const std::string& where) {
  std::string out;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t open = text.find("${", i);
    if (open == std::string::npos) break;
    const std::size_t close = text.find('}', open);
    if (close == std::string::npos) {
      throw InputError(fmt::format("{}: '${{' without a closing '}}' in '{}'", where, text));
    }
    out += text.substr(i, open - i);
    const std::string inner = text.substr(open + 2, close - open - 2);
    const std::size_t dash = inner.find(":-");
    const std::string name = inner.substr(0, dash);
    const char* value = std::getenv(name.c_str());
    if (value != nullptr && *value != '\0') {
      out += value;
    } else if (dash != std::string::npos) {
      out += inner.substr(dash + 2);
    } else {
      throw InputError(fmt::format("{}: the environment variable {} is not set", where, name));
    }
    i = close + 1;
  }
  return out + text.substr(std::min(i, text.size()));
}

}  // namespace superdyna::sweep
