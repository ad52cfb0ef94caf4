#include "lidartag/driver/io/pcap_writer.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <vector>

#include "io/file_size_limit.hpp"
#include "lidartag/driver/io/pcap_source.hpp"

namespace lidartag::velodyne {
namespace {

std::vector<uint8_t> read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
uint32_t le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}
uint16_t be16(const uint8_t* p) {
  return static_cast<uint16_t>((p[0] << 8) | p[1]);
}
uint16_t ones_complement(const uint8_t* p, size_t n, uint32_t sum = 0) {
  for (size_t i = 0; i + 1 < n; i += 2) sum += be16(p + i);
  if (n % 2) sum += static_cast<uint32_t>(p[n - 1]) << 8;
  while (sum >> 16) sum = (sum & 0xFFFF) + (sum >> 16);
  return static_cast<uint16_t>(sum);
}

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("lidartag_pcap_writer_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

std::vector<uint8_t> test_payload(size_t n) {
  std::vector<uint8_t> p(n);
  for (size_t i = 0; i < n; ++i) p[i] = static_cast<uint8_t>(i * 7 + 3);
  return p;
}

TEST(PcapWriter, WritesClassicEthernetFileWithMicrosecondTimestamps) {
  const std::string path = temp_path("header.pcap");
  {
    driver::PcapWriter writer(path);
    const auto payload = test_payload(1206);
    writer.write_udp(payload, 1'700'000'000'123'456'789, 2368);
    EXPECT_EQ(writer.records(), 1u);
    writer.close();
    EXPECT_FALSE(writer.is_open());
  }
  const auto bytes = read_all(path);
  ASSERT_EQ(bytes.size(), 24u + 16u + 1248u);
  EXPECT_EQ(le32(bytes.data()), 0xA1B2C3D4u);  // classic pcap, microsecond resolution
  EXPECT_EQ(le32(bytes.data() + 20), 1u);      // LINKTYPE_ETHERNET
  const uint8_t* rec = bytes.data() + 24;
  EXPECT_EQ(le32(rec), 1'700'000'000u);
  EXPECT_EQ(le32(rec + 4), 123'456u);
  EXPECT_EQ(le32(rec + 8), 1248u);   // caplen: a full VLP-16 data frame
  EXPECT_EQ(le32(rec + 12), 1248u);  // len
  std::filesystem::remove(path);
}

TEST(PcapWriter, BuildsEthernetIpv4UdpFrameWithValidChecksums) {
  const std::string path = temp_path("frame.pcap");
  const auto payload = test_payload(513);  // odd length exercises the checksum padding
  {
    driver::PcapWriter writer(path);
    writer.write_udp(payload, 0, 8308, 0x0A000002, 0x0A0000FF, 40000);
  }
  const auto bytes = read_all(path);
  ASSERT_EQ(bytes.size(), 24u + 16u + 14u + 20u + 8u + 513u);
  const uint8_t* eth = bytes.data() + 40;
  EXPECT_EQ(be16(eth + 12), 0x0800);
  const uint8_t* ip = eth + 14;
  EXPECT_EQ(ip[0], 0x45);
  EXPECT_EQ(be16(ip + 2), 20 + 8 + 513);
  EXPECT_EQ(be16(ip + 6) & 0x3FFF, 0);  // not a fragment
  EXPECT_EQ(ip[9], 17);
  EXPECT_EQ(ones_complement(ip, 20), 0xFFFF) << "IPv4 header checksum";
  EXPECT_EQ(be16(ip + 12), 0x0A00);
  EXPECT_EQ(be16(ip + 14), 0x0002);
  EXPECT_EQ(be16(ip + 16), 0x0A00);
  EXPECT_EQ(be16(ip + 18), 0x00FF);
  const uint8_t* udp = ip + 20;
  EXPECT_EQ(be16(udp), 40000);
  EXPECT_EQ(be16(udp + 2), 8308);
  EXPECT_EQ(be16(udp + 4), 8 + 513);
  uint32_t pseudo = ones_complement(ip + 12, 8);
  pseudo += 17 + 8 + 513;
  EXPECT_EQ(ones_complement(udp, 8 + 513, pseudo), 0xFFFF) << "UDP checksum";
  EXPECT_TRUE(std::equal(payload.begin(), payload.end(), udp + 8));
  std::filesystem::remove(path);
}

TEST(PcapWriter, SourcePortDefaultsToDestinationPort) {
  const std::string path = temp_path("port.pcap");
  {
    driver::PcapWriter writer(path);
    writer.write_udp(test_payload(10), 0, 2368);
  }
  const auto bytes = read_all(path);
  ASSERT_GE(bytes.size(), 40u + 42u);
  const uint8_t* ip = bytes.data() + 40 + 14;
  EXPECT_EQ(be16(ip + 20), 2368);
  EXPECT_EQ(be16(ip + 22), 2368);
  EXPECT_EQ(be16(ip + 12), 0xC0A8);  // 192.168.1.201 by default
  EXPECT_EQ(be16(ip + 14), 0x01C9);
  EXPECT_EQ(be16(ip + 16), 0xFFFF);  // broadcast
  std::filesystem::remove(path);
}

TEST(PcapWriter, SameInputsGiveIdenticalBytes) {
  auto write = [](const std::string& path) {
    driver::PcapWriter writer(path);
    for (int i = 0; i < 5; ++i) {
      writer.write_udp(test_payload(1206), 1'000'000'000LL * i + 1327100LL * i, 2368);
      writer.write_udp(test_payload(512), 1'000'000'000LL * i + 500, 8308);
    }
  };
  const std::string a = temp_path("a.pcap"), b = temp_path("b.pcap");
  write(a);
  write(b);
  const auto bytes_a = read_all(a);
  EXPECT_EQ(bytes_a.size(), 24u + 5u * (16u + 1248u) + 5u * (16u + 554u));
  EXPECT_EQ(bytes_a, read_all(b));
  std::filesystem::remove(a);
  std::filesystem::remove(b);
}

TEST(PcapWriter, NegativeTimesKeepMicrosecondsInRange) {
  const std::string path = temp_path("neg.pcap");
  {
    driver::PcapWriter writer(path);
    writer.write_udp(test_payload(4), -1500, 2368);  // -1.5 us -> -2 us = -1 s + 999998 us
  }
  const auto bytes = read_all(path);
  ASSERT_GE(bytes.size(), 40u);
  EXPECT_EQ(le32(bytes.data() + 24), 0xFFFFFFFFu);
  EXPECT_EQ(le32(bytes.data() + 28), 999'998u);
  std::filesystem::remove(path);
}

TEST(PcapWriter, UnwritablePathThrowsIoErrorNamingIt) {
  const std::string path = "/nonexistent-dir-lidartag/x.pcap";
  try {
    driver::PcapWriter writer(path);
    FAIL() << "expected driver::IoError";
  } catch (const driver::IoError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(PcapWriter, RejectsOversizedPayloadAndWritesAfterClose) {
  const std::string path = temp_path("big.pcap");
  driver::PcapWriter writer(path);
  EXPECT_THROW(writer.write_udp(test_payload(driver::PcapWriter::kMaxPayload + 1), 0, 2368),
               driver::IoError);
  writer.close();
  EXPECT_THROW(writer.write_udp(test_payload(4), 0, 2368), driver::IoError);
  writer.close();  // idempotent
  std::filesystem::remove(path);
}

using test::FileSizeLimit;

size_t packets_in(const std::string& path) {
  driver::PcapSource source(path);
  driver::RawPacket packet;
  size_t n = 0;
  while (source.next(packet, std::chrono::milliseconds(10)) == driver::ReadStatus::kPacket) ++n;
  EXPECT_EQ(source.stats().truncated, 0u);
  return n;
}

TEST(PcapWriter, AFullDiskKeepsTheWholeRecordsBeforeItAndSaysHowMany) {
  const std::string path = temp_path("full.pcap");
  constexpr size_t kRecord = 16 + 1248;
  constexpr rlim_t kLimit = 500'000;  // 24 + 395 whole records and part of the next
  driver::PcapWriter writer(path);
  size_t taken = 0;
  driver::PcapWriteStatus status = driver::PcapWriteStatus::kOk;
  {
    FileSizeLimit limit(kLimit);
    for (; taken < 2000; ++taken) {
      status = writer.append_udp(test_payload(1206), 1'000'000 * static_cast<int64_t>(taken), 2368);
      if (status != driver::PcapWriteStatus::kOk) break;
    }
  }
  EXPECT_EQ(status, driver::PcapWriteStatus::kWriteError);
  // The failing block was written in part: its whole records stay, the torn one is cut off.
  const uint64_t whole = (kLimit - 24) / kRecord;
  EXPECT_EQ(writer.records(), whole);
  EXPECT_GT(taken, whole);
  EXPECT_TRUE(writer.failed());
  EXPECT_EQ(writer.error(), "cannot write '" + path + "': File too large");
  EXPECT_EQ(std::filesystem::file_size(path), 24 + whole * kRecord);
  // Nothing more is taken, even with room again; close() reports the failure.
  EXPECT_EQ(writer.append_udp(test_payload(4), 0, 2368), driver::PcapWriteStatus::kWriteError);
  EXPECT_FALSE(writer.flush());
  EXPECT_THROW(writer.close(), driver::IoError);
  EXPECT_EQ(writer.records(), whole);
  // The file is a valid capture of exactly those records.
  EXPECT_EQ(packets_in(path), whole);
  std::filesystem::remove(path);
}

TEST(PcapWriter, RecordsReachTheFileOnFlushAndOnClose) {
  const std::string path = temp_path("flush.pcap");
  driver::PcapWriter writer(path);
  EXPECT_EQ(std::filesystem::file_size(path), 24u);  // the header at once: creatable and writable
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(writer.append_udp(test_payload(100), i, 2368), driver::PcapWriteStatus::kOk);
  EXPECT_EQ(writer.records(), 3u);
  EXPECT_EQ(std::filesystem::file_size(path), 24u);  // buffered
  EXPECT_TRUE(writer.flush());
  EXPECT_EQ(std::filesystem::file_size(path), 24u + 3u * (16u + 142u));
  EXPECT_EQ(writer.append_udp(test_payload(100), 3, 2368), driver::PcapWriteStatus::kOk);
  writer.close();
  EXPECT_EQ(packets_in(path), 4u);
  EXPECT_EQ(writer.append_udp(test_payload(100), 4, 2368), driver::PcapWriteStatus::kClosed);
  std::filesystem::remove(path);
}

TEST(PcapWriter, AFileThatCannotBeWrittenFailsAtCreation) {
  // /dev/full takes the open and refuses every byte: the header write fails in the constructor.
  try {
    driver::PcapWriter writer("/dev/full");
    FAIL() << "expected driver::IoError";
  } catch (const driver::IoError& e) {
    EXPECT_EQ(std::string(e.what()), "cannot write '/dev/full': No space left on device");
  }
}

}  // namespace
}  // namespace lidartag::velodyne
