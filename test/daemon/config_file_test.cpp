// Configuration files and values that must be refused before anything runs: files that are not
// regular files or are too large, keys given twice, second documents, and the error line that
// shortens what it quotes.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "lidartag/daemon/config.hpp"
#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

std::string temp_path(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartag_config_file");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

// The ConfigError `body` throws (fails the test when it throws none).
template <class F>
ConfigError config_error(F&& body) {
  try {
    body();
  } catch (const ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "no ConfigError";
  return ConfigError("", "");
}

TEST(ConfigFile, DirectoryDeviceAndFifoAreNotConfigurationFiles) {
  const std::string dir = temp_path("a_directory");
  std::filesystem::create_directories(dir);
  const std::string fifo = temp_path("a_fifo");
  std::filesystem::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::pair<std::string, std::string> cases[] = {
      {dir, "config: '" + dir + "': not a regular file (a directory)"},
      {"/dev/zero", "config: '/dev/zero': not a regular file (a character device)"},
      // Opened without waiting for a writer: the test would hang otherwise.
      {fifo, "config: '" + fifo + "': not a regular file (a FIFO)"},
      {"/nonexistent.yaml", "config: '/nonexistent.yaml': cannot read the file: No such file"},
  };
  for (const auto& [path, message] : cases) {
    SCOPED_TRACE(path);
    const ConfigError e = config_error([&] { load_config(path); });
    EXPECT_EQ(std::string(e.what()).rfind(message, 0), 0u) << e.what();
    EXPECT_EQ(e.key(), "config");
    EXPECT_THROW(load_detector_config(path), ConfigError);  // the CLI reads files the same way
  }
}

TEST(ConfigFile, AtMostOneMebibyte) {
  // Exactly the limit: a valid file (a comment padding it) loads.
  const std::string fits = temp_path("fits.yaml");
  {
    std::ofstream out(fits);
    const std::string head = "lcm:\n  url: memq://\n#";
    out << head << std::string(kMaxConfigBytes - head.size() - 1, 'x') << "\n";
  }
  ASSERT_EQ(std::filesystem::file_size(fits), kMaxConfigBytes);
  EXPECT_EQ(load_config(fits).lcm.url, "memq://");

  // One byte more is refused by its size, before it is read.
  const std::string big = temp_path("big.yaml");
  std::filesystem::copy_file(fits, big, std::filesystem::copy_options::overwrite_existing);
  std::ofstream(big, std::ios::app) << "\n";
  const ConfigError e = config_error([&] { load_config(big); });
  EXPECT_EQ(std::string(e.what()),
            "config: '" + big + "': 1048577 bytes: larger than the limit of 1048576 bytes (1 MiB)");
}

TEST(ConfigFile, DuplicateKeysNameThePathAndBothLines) {
  const std::pair<std::string, std::string> cases[] = {
      {"lcm:\n  url: memq://\n  publish_raw: true\n  url: udpm://\n",
       "lcm.url: duplicate key (lines 2 and 4 of config)"},
      {"sensors:\n  - name: a\n  - name: b\n    source:\n      data_port: 2370\n"
       "      position_port: 8310\n      data_port: 2371\n",
       "sensors[1].source.data_port: duplicate key (lines 5 and 7 of config)"},
      {"status:\n  period_s: 1\nstatus:\n  period_s: 2\n",
       "status: duplicate key (lines 1 and 3 of config)"},
      {"detector: {tag_sizes_m: [0.5], tag_sizes_m: [0.8]}\n",
       "detector.tag_sizes_m: duplicate key (lines 1 and 1 of config)"},
      // An alias is one event: the key it stands beside is still compared.
      {"a: &x {b: 1}\nc: *x\na: 2\n", "a: duplicate key (lines 1 and 3 of config)"},
  };
  for (const auto& [yaml, message] : cases) {
    SCOPED_TRACE(yaml);
    EXPECT_EQ(std::string(config_error([&] { parse_config(yaml); }).what()), message);
  }
  // The same key in two different maps is no duplicate.
  EXPECT_NO_THROW(parse_config("sensors:\n  - name: a\n  - name: b\n    channel_prefix: B_\n"));

  // Files name themselves; --set values are checked the same way, under their key.
  const std::string file = temp_path("duplicate.yaml");
  std::ofstream(file) << "lcm:\n  url: memq://\nlogging:\n  level: info\n  level: debug\n";
  EXPECT_EQ(std::string(config_error([&] { load_config(file); }).what()),
            "logging.level: duplicate key (lines 4 and 5 of config " + file + ")");
  EXPECT_EQ(std::string(config_error([&] { parse_config("", {"lcm={url: a, url: b}"}); }).what()),
            "lcm.url: duplicate key (lines 1 and 1 of --set lcm)");
}

TEST(ConfigFile, OneDocumentOnly) {
  const ConfigError e = config_error([] { parse_config("lcm:\n  url: memq://\n---\nbad: 1\n"); });
  EXPECT_EQ(std::string(e.what()),
            "config: a second YAML document (line 3): one document holds the whole configuration");
}

TEST(ConfigFile, DeepNestingIsAnErrorNotACrash) {
  const std::string deep(100000, '[');
  const ConfigError e = config_error([&] { parse_config("a: " + deep); });
  EXPECT_NE(std::string(e.what()).find("nested too deeply"), std::string::npos) << e.what();
}

TEST(ConfigFile, ErrorLinesShortenLongValuesKeysAndReasons) {
  // A 1 MB bad value (a file may not be larger): the line quotes its first 80 characters and its
  // size.
  const std::string value(1'000'000, '7');
  const ConfigError e = config_error([&] { parse_config("status:\n  period_s: " + value + "\n"); });
  const std::string line = e.what();
  EXPECT_EQ(line, "status.period_s: '" + std::string(80, '7') +
                      "... (1000000 bytes)': expected a number");
  EXPECT_EQ(e.value().size(), value.size());  // the exception keeps it whole

  // The same through --set, and a long unknown key.
  const std::string word(5000, 'w');
  const std::string set_line =
      config_error([&] { parse_config("", {"logging.level=" + word}); }).what();
  EXPECT_LT(set_line.size(), 300u) << set_line;
  EXPECT_NE(set_line.find("... (5000 bytes)"), std::string::npos);
  const std::string key_line = config_error([&] { parse_config("? " + word + "\n: 1\n"); }).what();
  EXPECT_LT(key_line.size(), 300u);
  EXPECT_NE(key_line.find("unknown key"), std::string::npos) << key_line;

  // Always one line: a value with line breaks is shown escaped.
  const std::string multi =
      config_error([&] { parse_config("logging:\n  level: \"a\\nb\\tc\\u0001\"\n"); }).what();
  EXPECT_EQ(multi.find('\n'), std::string::npos);
  EXPECT_NE(multi.find("'a\\nb\\tc\\x01'"), std::string::npos) << multi;
}

TEST(ConfigFile, ClipTextKeepsCharactersWholeAndSaysHowLongTheTextWas) {
  EXPECT_EQ(clip_text("short"), "short");
  EXPECT_EQ(clip_text(std::string(80, 'a')), std::string(80, 'a'));
  EXPECT_EQ(clip_text(std::string(81, 'a')), std::string(80, 'a') + "... (81 bytes)");
  // Four two-byte characters, three shown: never half of one.
  EXPECT_EQ(clip_text("\xc3\xa9\xc3\xa9\xc3\xa9\xc3\xa9", 3),
            "\xc3\xa9\xc3\xa9\xc3\xa9... (8 bytes)");
  // Stray continuation bytes cannot make the output long.
  EXPECT_LT(clip_text("a" + std::string(100000, '\x80'), 10).size(), 60u);
  EXPECT_EQ(clip_text("x\ny\x7f"), "x\\ny\\x7f");
}

}  // namespace
}  // namespace lidartag::daemon
