// The command-line conventions every program keeps (issue 12, item 5): results on stdout and
// everything else on stderr, --version, one exit status convention, model names in any case, a
// truncated capture pointing to --partial, dump refusing to mix old and new files, progress only
// on a terminal.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "lidartag/version.hpp"
#include "run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using lidartag::testing::run_command;
using lidartag::testing::run_split;
using lidartag::testing::run_tool;
using Result = lidartag::testing::ToolResult;

const std::string kCli = LIDARTAG_CLI;
const std::string kDaemon = LIDARTAGD;
const std::string kSpy = LIDARTAG_SPY;
const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";

class TempDir {
 public:
  TempDir()
      : path_(fs::temp_directory_path() / ("lidartag_hygiene_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
};

void write_file(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(CliVersion, EveryProgramPrintsTheBuiltVersionOnStdout) {
  EXPECT_EQ(std::string(lidartag::kVersion), LIDARTAG_PROJECT_VERSION);
  for (const auto& [program, name] :
       {std::pair{kCli, "lidartag"}, {kDaemon, "lidartagd"}, {kSpy, "lidartag-spy"}}) {
    const Result r = run_split(program + " --version");
    EXPECT_EQ(r.exit_code, 0) << name;
    EXPECT_EQ(r.out, std::string(name) + " " + lidartag::kVersionString + "\n");
    EXPECT_EQ(r.err, "") << name;
  }
  // In a git checkout the commit is named: what git describes now (the tree may have become
  // dirty since the build, or clean).
  const Result git =
      run_command("git -C " LIDARTAG_SOURCE_DIR " describe --tags --always --dirty 2>/dev/null");
  auto commit = [](std::string s) {
    while (!s.empty() && s.back() == '\n') s.pop_back();
    if (s.size() > 6 && s.compare(s.size() - 6, 6, "-dirty") == 0) s.resize(s.size() - 6);
    return s;
  };
  EXPECT_EQ(commit(lidartag::kGitDescribe), git.exit_code == 0 ? commit(git.out) : "");
}

// The version script outside a git checkout, and inside someone else's: the project version only.
TEST(CliVersion, WithoutItsOwnGitCheckoutTheProjectVersionAlone) {
  TempDir dir;
  const std::string outer = dir / "outer", source = dir / "outer/lidartag-src";
  fs::create_directories(source);
  const std::string script = std::string(LIDARTAG_SOURCE_DIR) + "/cmake/WriteVersion.cmake";
  const std::string tmpl = std::string(LIDARTAG_SOURCE_DIR) + "/cmake/version.hpp.in";
  auto generate = [&](const std::string& out) {
    return run_command("cmake -DSOURCE_DIR=" + source + " -DTEMPLATE=" + tmpl + " -DOUTPUT=" + out +
                       " -DLIDARTAG_VERSION=9.8.7 -P " + script + " 2>&1");
  };
  ASSERT_EQ(generate(dir / "plain.hpp").exit_code, 0);
  const std::string plain = read_file(dir / "plain.hpp");
  EXPECT_TRUE(contains(plain, "kVersion = \"9.8.7\"")) << plain;
  EXPECT_TRUE(contains(plain, "kGitDescribe = \"\"")) << plain;
  EXPECT_TRUE(contains(plain, "kVersionString = \"9.8.7\"")) << plain;
  if (run_command("git --version").exit_code != 0) GTEST_SKIP() << "no git";
  ASSERT_EQ(run_command("cd " + outer +
                        " && git init -q && git -c user.name=t -c user.email=t@t commit -q "
                        "--allow-empty -m x 2>&1")
                .exit_code,
            0);
  ASSERT_EQ(generate(dir / "nested.hpp").exit_code, 0);
  EXPECT_TRUE(contains(read_file(dir / "nested.hpp"), "kVersionString = \"9.8.7\""));
}

TEST(CliOutput, WarningsGoToStderrSoJsonStaysParseable) {
  // The demo is a VLP-32C: --model vlp16 contradicts its packet timing. Decoded as a VLP-16 its
  // packets make no complete rotation, so --partial keeps the incomplete ones.
  const Result r = run_split(kCli + " detect " + kDemo + " --model vlp16 --json --partial");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  size_t n = 0;
  while (std::getline(lines, line)) {
    EXPECT_FALSE(nlohmann::json::parse(line, nullptr, false).is_discarded()) << line;
    ++n;
  }
  EXPECT_GT(n, 0u);
  // The warning names the model given, the packets' period and the model it fits.
  EXPECT_TRUE(contains(r.err, "lidartag: warning: ")) << r.err;
  for (const char* words : {"vlp16", "664 us per packet", "vlp32c"})
    EXPECT_TRUE(contains(r.err, words)) << words << ": " << r.err;
  EXPECT_FALSE(contains(r.out, "warning")) << r.out;
}

TEST(CliOutput, ExplicitModelContradictingTheTimingIsWarnedByEveryCaptureCommand) {
  TempDir dir;
  for (const std::string& command :
       {"detect " + kDemo + " --model VLP16 --partial",
        "dump " + kDemo + " --model vlp16 --partial --out " + (dir / "scans")}) {
    const Result r = run_split(kCli + " " + command);
    EXPECT_EQ(r.exit_code, 0) << command << r.err;
    for (const char* words : {"warning: ", "664 us per packet", "vlp32c"})
      EXPECT_TRUE(contains(r.err, words)) << command << ": " << r.err;
  }
  // The right model, in any spelling: no warning.
  const Result right = run_split(kCli + " detect " + kDemo + " --model VLP-32C");
  EXPECT_EQ(right.exit_code, 0);
  EXPECT_EQ(right.err, "");
}

TEST(CliModelNames, AnyCaseAndPunctuation) {
  for (const char* name : {"VLP-32C", "Vlp32c", "vlp_32c", "ultra-puck"}) {
    const Result r = run_tool(std::string("info --model ") + name + " " + kDemo);
    EXPECT_EQ(r.exit_code, 0) << name << r.out;
    EXPECT_TRUE(contains(r.out, "model:          vlp32c (from --model)")) << name << r.out;
  }
  const Result found =
      run_tool("detect " + kDemo + " --model VLP-32C --tag-size 0.8 --tag-size 0.6", false);
  EXPECT_TRUE(contains(found.out, "tag16h5 id 0 in 10, tag16h5 id 1 in 10")) << found.out;
  const Result bad = run_tool("info --model VLP-64 " + kDemo);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_TRUE(contains(bad.out, "vlp16, puck-hires, vlp32c, hdl32e, vls128")) << bad.out;
}

TEST(CliTruncatedCapture, TheMessageNamesPartial) {
  TempDir dir;
  // The first 100 kB of the demo: a part of its first rotation, the last record cut short.
  const std::string demo = read_file(kDemo);
  ASSERT_GT(demo.size(), 100000u);
  const std::string cut = dir / "cut.pcap";
  write_file(cut, demo.substr(0, 100000));

  Result r = run_split(kCli + " detect " + cut);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "no complete rotation")) << r.err;
  EXPECT_TRUE(contains(r.err, "--partial detects in them")) << r.err;
  r = run_split(kCli + " detect --partial --json " + cut);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "\"sequence\":0")) << r.out;

  r = run_split(kCli + " dump " + cut + " --out " + (dir / "a"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "--partial writes them")) << r.err;
  r = run_split(kCli + " dump --partial " + cut + " --out " + (dir / "b"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "b/rotation_000000.pcd"));

  // Nothing on the data port at all: the counts say why.
  r = run_split(kCli + " detect " + cut + " --data-port 9");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "no rotation: 0 data packets on port 9")) << r.err;
}

TEST(CliDump, RefusesANonEmptyFolderAndForceRemovesOnlyItsOwnFiles) {
  TempDir dir;
  const std::string out = dir / "scans";
  fs::create_directories(out);
  write_file(out + "/notes.txt", "keep me");
  write_file(out + "/scan_000042.pcd", "an old rotation (the name earlier builds wrote)");
  write_file(out + "/rotation_000043.pcd", "an old rotation");
  write_file(out + "/scan_0001.pcd", "not a name dump writes");

  Result r = run_split(kCli + " dump " + kDemo + " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_TRUE(contains(r.err, "is not empty (2 PCD files of an earlier dump, 2 other entries)"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "--force")) << r.err;
  EXPECT_TRUE(fs::exists(out + "/scan_000042.pcd"));
  EXPECT_FALSE(fs::exists(out + "/rotation_000001.pcd"));

  r = run_split(kCli + " dump " + kDemo + " --out " + out + " --force");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_file(out + "/notes.txt"), "keep me");
  EXPECT_TRUE(fs::exists(out + "/scan_0001.pcd"));
  EXPECT_FALSE(fs::exists(out + "/scan_000042.pcd"));
  EXPECT_FALSE(fs::exists(out + "/rotation_000043.pcd"));
  // The demo's complete rotations are 1 to 10 (0 and 11 are its partial ends).
  for (int i = 1; i <= 10; ++i) {
    const std::string number = std::to_string(i);
    EXPECT_TRUE(
        fs::exists(out + "/rotation_" + std::string(6 - number.size(), '0') + number + ".pcd"))
        << i;
  }
  EXPECT_FALSE(fs::exists(out + "/rotation_000000.pcd"));
  EXPECT_FALSE(fs::exists(out + "/rotation_000011.pcd"));
  EXPECT_TRUE(contains(r.out, "wrote 10 PCD files")) << r.out;

  // A new folder, or an empty one, needs no --force.
  fs::create_directories(dir / "empty");
  EXPECT_EQ(run_split(kCli + " dump " + kDemo + " --out " + (dir / "empty")).exit_code, 0);
  EXPECT_EQ(run_split(kCli + " dump " + kDemo + " --out " + (dir / "new/deeper")).exit_code, 0);
}

// `script` runs a command on a pseudo-terminal: there the bar is drawn, in a pipe never.
TEST(CliProgress, DrawnOnATerminalOnly) {
  if (run_command("script --version 2>&1").exit_code != 0) GTEST_SKIP() << "no script(1)";
  TempDir dir;
  const std::string scene = LIDARTAG_SOURCE_DIR "/pcaps/demo.yaml";
  const std::string commands[] = {
      "sim " + scene + " --rotations 2 --out " + (dir / "sim.pcap"),
      "dump " + kDemo + " --force --out " + (dir / "scans"),
      "detect " + kDemo + " --json",
      "render " + kDemo + " --rotation 9 -o " + (dir / "render"),
  };
  for (const std::string& command : commands) {
    const Result tty =
        run_command("script -qec '" + kCli + " " + command + " >/dev/null' /dev/null");
    EXPECT_EQ(tty.exit_code, 0) << command << tty.out;
    EXPECT_TRUE(contains(tty.out, "\r[")) << command << ": " << tty.out;
    EXPECT_TRUE(contains(tty.out, "%")) << command;
    const Result pipe = run_split(kCli + " " + command);
    EXPECT_EQ(pipe.exit_code, 0) << command;
    EXPECT_FALSE(contains(pipe.err, "\r")) << command;
    EXPECT_FALSE(contains(pipe.out, "\r")) << command;
  }
}

TEST(CliExitCodes, SameConventionInEveryProgram) {
  TempDir dir;
  write_file(dir / "bad.yaml", "detector:\n  features:\n    zeta: 0.5\n");
  // A configuration error: 2 in both programs.
  const Result cli = run_split(kCli + " detect " + kDemo + " --config " + (dir / "bad.yaml"));
  EXPECT_EQ(cli.exit_code, 2) << cli.err;
  EXPECT_TRUE(contains(cli.err, "detector.features.zeta")) << cli.err;
  const Result daemon = run_split(kDaemon + " --config " + (dir / "bad.yaml") + " --print-config");
  EXPECT_EQ(daemon.exit_code, 2) << daemon.err;
  // A usage error: 2.
  EXPECT_EQ(run_split(kCli + " detect " + kDemo + " --no-such-option").exit_code, 2);
  EXPECT_EQ(run_split(kDaemon + " --no-such-option").exit_code, 2);
  // A runtime failure (an input that cannot be read): 1.
  write_file(dir / "garbage.pcap", "x");
  EXPECT_EQ(run_split(kCli + " detect " + (dir / "garbage.pcap")).exit_code, 1);
  EXPECT_EQ(
      run_split(kDaemon + " --replay " + (dir / "garbage.pcap") + " --lcm-url memq://").exit_code,
      1);
  // Help and version: 0.
  EXPECT_EQ(run_split(kCli + " --help").exit_code, 0);
  EXPECT_EQ(run_split(kCli + " tag --help").exit_code, 0);
  EXPECT_EQ(run_split(kDaemon + " --help").exit_code, 0);
}

}  // namespace

#if LIDARTAG_HAVE_MAN
TEST(CliManPages, OnePerProgramAndCommandWithEveryOption) {
  const std::string dir = LIDARTAG_MAN_DIR;
  // Every command of `lidartag --help` has a page, with every option of its own --help.
  const Result help = run_command(kCli + " --help");
  std::vector<std::string> pages = {"lidartag", "lidartagd"};
  const size_t subs = help.out.find("Subcommands:");
  ASSERT_NE(subs, std::string::npos);
  std::istringstream lines(help.out.substr(subs));
  std::string line;
  std::getline(lines, line);
  while (std::getline(lines, line))
    if (line.size() > 2 && line[2] != ' ')
      pages.push_back("lidartag-" + line.substr(2, line.find(' ', 2) - 2));
  EXPECT_GE(pages.size(), 7u);
  for (const std::string& page : pages) {
    SCOPED_TRACE(page);
    const std::string file = dir + "/" + page + ".1";
    ASSERT_TRUE(fs::exists(file)) << file;
    const std::string roff = read_file(file);
    std::string title = page;
    for (char& c : title) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    EXPECT_TRUE(contains(roff, ".TH " + title + " \"1\"")) << roff.substr(0, 300);
    EXPECT_TRUE(contains(roff, ".SH \"EXIT STATUS\"")) << page;
    EXPECT_TRUE(contains(roff, ".SH \"SEE ALSO\"")) << page;
    const std::string program = page == "lidartagd" ? kDaemon : kCli;
    const std::string sub = page.rfind("lidartag-", 0) == 0 ? page.substr(9) : "";
    const Result own = run_command(program + " " + sub + " --help");
    std::istringstream options(own.out);
    size_t count = 0;
    while (std::getline(options, line)) {
      if (line.rfind("  --", 0) != 0) continue;
      std::string option = line.substr(2, line.find_first_of(" ,", 2) - 2);
      // roff escapes every '-'.
      std::string escaped;
      for (char c : option) escaped += c == '-' ? std::string("\\-") : std::string(1, c);
      EXPECT_TRUE(contains(roff, escaped)) << option;
      ++count;
    }
    EXPECT_GE(count, 1u);
  }
}
#endif

#if LIDARTAG_HAVE_COMPLETION
// Runs the generated completion function in bash as if TAB was pressed after `words`.
std::string complete(const std::string& program, const std::string& words) {
  const std::string script = std::string(LIDARTAG_COMPLETION_DIR) + "/" + program;
  const Result r = run_command("bash -c 'source " + script + "; COMP_WORDS=(" + words +
                               "); COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _" + program +
                               "; printf \"%s\\n\" \"${COMPREPLY[@]}\"' 2>&1");
  return r.out;
}

TEST(CliCompletion, CommandsOptionsAndValues) {
  EXPECT_EQ(complete("lidartag", "lidartag de"), "detect\n");
  EXPECT_EQ(complete("lidartag", "lidartag t"), "tag\n");
  EXPECT_EQ(complete("lidartag", "lidartag tag --con"), "--convention\n");
  EXPECT_EQ(complete("lidartag", "lidartag tag tag16h5 --convention \"\""), "outer\nblack\n");
  EXPECT_EQ(complete("lidartag", "lidartag detect x.pcap --model vlp3"), "vlp32c\n");
  EXPECT_EQ(complete("lidartag", "lidartag tag --page A"), "A5\nA4\nA3\nA2\nA1\nA0\n");
  EXPECT_TRUE(contains(complete("lidartag", "lidartag tag tag3"), "tag36h10\ntag36h11\n"));
  EXPECT_TRUE(contains(complete("lidartag", "lidartag detect --family tag2"), "tag25h9\n"));
  EXPECT_EQ(complete("lidartag", "lidartag tag --outer-size 1"), "\n");  // a length: nothing
  EXPECT_EQ(complete("lidartagd", "lidartagd --log-level w"), "warn\n");
  EXPECT_EQ(complete("lidartagd", "lidartagd --repl"), "--replay\n--replay-lcm\n");
  EXPECT_EQ(complete("lidartagd", "lidartagd --vers"), "--version\n");
  // Files where a file goes.
  TempDir dir;
  write_file(dir / "scan.pcap", "");
  EXPECT_EQ(complete("lidartag", "lidartag detect " + (dir / "sc")), (dir / "scan.pcap") + "\n");
  // Every option of every command completes.
  for (const char* sub : {"detect", "dump", "info", "render", "sim", "tag"}) {
    const std::string all = complete("lidartag", std::string("lidartag ") + sub + " --");
    const Result help = run_command(kCli + " " + sub + " --help");
    std::istringstream lines(help.out);
    std::string line;
    while (std::getline(lines, line)) {
      if (line.rfind("  --", 0) != 0) continue;
      const std::string option = line.substr(2, line.find_first_of(" ,", 2) - 2);
      EXPECT_TRUE(contains(all, option + "\n")) << sub << " " << option;
    }
  }
}
#endif
