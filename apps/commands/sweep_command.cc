#include "commands/sweep_command.h"

#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/sweep/dispatch.h"
#include "superdyna/sweep/report_html.h"
#include "superdyna/sweep/sweep.h"
#include "superdyna/sweep/tables.h"

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

class SweepCommand : public Command {
 public:
  explicit SweepCommand(CLI::App& app) {
    sub_ = app.add_subcommand(
        "sweep",
        "Run a matrix of sequences x configs x runs from a spec file (bench/*.sweep.yaml), score "
        "every cell, write Markdown / CSV tables and an HTML report; a killed sweep continues "
        "where it stopped");
    sub_->add_option("spec", spec_, "Sweep spec (YAML; see include/superdyna/sweep/spec.h)")
        ->required()
        ->check(CLI::ExistingFile);
    sub_->add_option("--out", out_, "Sweep folder: sequences/, cells/, tables/, report/")
        ->required();
    sub_->add_option("-j,--jobs", dispatch_.jobs, "Cells run at once (local and GNU parallel)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    sub_->add_option("--dispatch", dispatch_kind_,
                     "Where cells run: local (this process's workers), parallel (GNU parallel; "
                     "--sshlogin for other machines) or slurm (an sbatch job array, waited for)")
        ->check(CLI::IsMember({"local", "parallel", "slurm"}))
        ->capture_default_str();
    sub_->add_option("--sshlogin", dispatch_.ssh_logins,
                     "GNU parallel --sshlogin (repeatable; the machines must see --out and the "
                     "binary at the same paths)");
    sub_->add_option("--sbatch-arg", dispatch_.sbatch_args,
                     "Extra sbatch argument, e.g. --sbatch-arg=--partition=cpu (repeatable)");
    sub_->add_flag("--rerun-failed", rerun_failed_, "Run failed cells again (default: kept)");
    sub_->add_flag("--report-only", report_only_,
                   "Run nothing: tables and report from the cells finished so far");
    sub_->add_option("--task", task_,
                     "Run one task and exit (what dispatched workers run): sequence:I or cell:I");
  }

  CLI::App* subcommand() const override { return sub_; }

  int run() override {
    const fs::path self = fs::read_symlink("/proc/self/exe");
    const sweep::SweepSpec spec = sweep::loadSweepSpec(spec_);
    const sweep::SweepPlan plan = sweep::planSweep(spec, out_, self);
    dispatch_.kind = sweep::parseDispatchKind(dispatch_kind_);
    dispatch_.superdyna = self;
    dispatch_.spec = fs::absolute(spec_);
    dispatch_.out = plan.out;
    dispatch_.rerun_failed = rerun_failed_;
    if (task_) return runTask(spec, plan, *task_);
    if (!report_only_) {
      fs::create_directories(plan.out);
      prepareSequences(plan);
      runCells(spec, plan);
    }
    return report(spec, plan);
  }

 private:
  int runTask(const sweep::SweepSpec& spec, const sweep::SweepPlan& plan, const std::string& task) {
    const std::size_t colon = task.find(':');
    const std::string kind = task.substr(0, colon);
    std::size_t index = 0;
    try {
      index = std::stoul(task.substr(colon + 1));
    } catch (const std::exception&) {
      throw OptionError("--task", fmt::format("'{}' is not sequence:I or cell:I", task));
    }
    if (colon == std::string::npos || (kind != "sequence" && kind != "cell") ||
        index >= (kind == "cell" ? plan.cells.size() : plan.sequences.size())) {
      throw OptionError("--task", fmt::format("'{}' is not a task of this sweep", task));
    }
    if (kind == "sequence") {
      sweep::prepareSequence(plan, plan.sequences[index], sweep::buildRevision());
      fmt::print("sequence {} ready\n", plan.sequences[index].name);
      return 0;
    }
    const sweep::CellTask& cell = plan.cells[index];
    if (!sweep::cellNeeded(spec, plan, cell, rerun_failed_)) {
      fmt::print("{}: finished before\n", cell.id());
      return 0;
    }
    const sweep::CellResult r = sweep::runCell(spec, plan, cell, sweep::buildRevision());
    fmt::print("{}: {}\n", cell.id(), describe(r));
    return r.ok ? 0 : 1;
  }

  static std::string describe(const sweep::CellResult& r) {
    if (!r.ok) {
      // The cause and the last line of the log, which usually says why.
      std::string last = r.error.substr(0, r.error.find_last_not_of("\n ") + 1);
      last = last.substr(last.find_last_of('\n') + 1);
      const std::string first = r.error.substr(0, r.error.find('\n'));
      return "failed: " + (last == first ? first : first + " " + last);
    }
    return fmt::format("ATE {}, {:.1f} s, {:.1f} s CPU", sweep::formatMetres(r.ate_rmse_m),
                       r.wall_s, r.cpu_s);
  }

  void prepareSequences(const sweep::SweepPlan& plan) {
    std::vector<std::string> tasks;
    for (std::size_t i = 0; i < plan.sequences.size(); ++i) {
      if (sweep::sequenceNeeded(plan.sequences[i])) tasks.push_back(fmt::format("sequence:{}", i));
    }
    if (!tasks.empty()) fmt::print("simulating {} sequence(s)\n", tasks.size());
    std::fflush(stdout);
    std::mutex print;
    sweep::dispatchTasks(tasks, "sequences", dispatch_, [&](const std::string& task) {
      const auto& s = plan.sequences[std::stoul(task.substr(task.find(':') + 1))];
      try {
        sweep::prepareSequence(plan, s, sweep::buildRevision());
        const std::lock_guard lock(print);
        fmt::print("sequence {} simulated\n", s.name);
      } catch (const std::exception& e) {
        const std::lock_guard lock(print);
        fmt::print(stderr, "sequence {}: {}\n", s.name, e.what());
      }
      std::fflush(stdout);
    });
    for (const sweep::SequenceTask& s : plan.sequences) {
      if (sweep::sequenceNeeded(s)) {
        throw InputError(InputLocation(s.marker.parent_path() / (s.name + ".log")),
                         fmt::format("sequence '{}' was not simulated; its log says why", s.name));
      }
    }
  }

  void runCells(const sweep::SweepSpec& spec, const sweep::SweepPlan& plan) {
    std::vector<std::string> tasks;
    for (std::size_t i = 0; i < plan.cells.size(); ++i) {
      if (sweep::cellNeeded(spec, plan, plan.cells[i], rerun_failed_)) {
        tasks.push_back(fmt::format("cell:{}", i));
      }
    }
    fmt::print("{} cells: {} finished before, {} to run ({} dispatch)\n", plan.cells.size(),
               plan.cells.size() - tasks.size(), tasks.size(), dispatch_kind_);
    std::fflush(stdout);
    std::mutex print;
    std::size_t done = 0;
    sweep::dispatchTasks(tasks, "cells", dispatch_, [&](const std::string& task) {
      const sweep::CellTask& cell = plan.cells[std::stoul(task.substr(task.find(':') + 1))];
      std::string line;
      try {
        line = describe(sweep::runCell(spec, plan, cell, sweep::buildRevision()));
      } catch (const std::exception& e) {
        line = fmt::format("not run: {}", e.what());
      }
      const std::lock_guard lock(print);
      fmt::print("[{}/{}] {}: {}\n", ++done, tasks.size(), cell.id(), line);
      std::fflush(stdout);
    });
  }

  int report(const sweep::SweepSpec& spec, const sweep::SweepPlan& plan) const {
    const std::vector<sweep::CellResult> results = sweep::collectResults(spec, plan);
    const std::vector<sweep::CellGroup> groups = sweep::groupResults(spec, results);
    const std::vector<sweep::TableText> tables = sweep::allTables(spec, groups);
    sweep::writeTables(tables, plan.out / "tables");
    const fs::path page = sweep::writeHtmlReport(
        {spec, plan, groups, tables, sweep::buildRevision()}, plan.out / "report");
    fmt::print("\n### {}\n\n{}\n### {}\n\n{}\n", tables[0].title, tables[0].markdown,
               tables[1].title, tables[1].markdown);
    std::size_t failed = 0;
    for (const sweep::CellResult& r : results)
      failed += r.ok ? 0 : 1;
    const std::size_t missing = plan.cells.size() - results.size();
    fmt::print("tables: {}/tables/ (tables.md, *.csv); report: {}\n", plan.out.string(),
               page.string());
    if (failed + missing == 0) return 0;
    fmt::print("{} cell(s) failed, {} not finished: see their log.txt and result.json\n", failed,
               missing);
    return 1;
  }

  CLI::App* sub_ = nullptr;
  fs::path spec_;
  fs::path out_;
  std::string dispatch_kind_ = "local";
  sweep::DispatchOptions dispatch_;
  bool rerun_failed_ = false;
  bool report_only_ = false;
  std::optional<std::string> task_;
};

}  // namespace

std::unique_ptr<Command> makeSweepCommand(CLI::App& app) {
  return std::make_unique<SweepCommand>(app);
}

}  // namespace superdyna::apps
