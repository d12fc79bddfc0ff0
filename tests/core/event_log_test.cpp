// The event log stays bounded whatever is posted to it, and says what it let go.
#include <gtest/gtest.h>

#include <string>

#include "lode/event_log.hpp"

namespace {

using lode::EventLog;

TEST(EventLog, LongTextsAreCutAndSaySo) {
  EventLog log;
  log.post(0, 0, "refused", std::string(60'000, 'x'));
  const auto events = log.snapshot();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_LE(events[0].text.size(), EventLog::kMaxTextBytes);
  EXPECT_NE(events[0].text.find("[cut "), std::string::npos) << events[0].text.substr(0, 80);
  EXPECT_EQ(events[0].text.substr(0, 10), "xxxxxxxxxx");
}

TEST(EventLog, CutNeverSplitsAUtf8Character) {
  std::string text;
  while (text.size() < 3000) text += "\xC2\xB5m ";  // "µm "
  const std::string cut = lode::bounded_text(text, 100);
  const std::size_t note = cut.find("...[cut ");
  ASSERT_NE(note, std::string::npos);
  // The byte before the note ends a character: not a lead byte, and its sequence is whole.
  const auto last = static_cast<unsigned char>(cut[note - 1]);
  EXPECT_NE(last & 0xC0, 0xC0) << "cut after a UTF-8 lead byte";
  EXPECT_EQ(lode::bounded_text("short", 100), "short");
}

TEST(EventLog, KeepsTheHeadAndTheLatestAndCountsTheRest) {
  EventLog log;
  const std::size_t total = EventLog::kKeptHead + EventLog::kKeptTail + 10'000;
  for (std::size_t i = 0; i < total; ++i) log.post(static_cast<std::int64_t>(i), i, "warning", std::to_string(i));
  const auto kept = log.snapshot();
  ASSERT_EQ(kept.size(), EventLog::kKeptHead + EventLog::kKeptTail);
  EXPECT_EQ(log.posted(), total);
  EXPECT_EQ(log.dropped(), 10'000u);
  EXPECT_EQ(kept.front().text, "0");  // how the run started
  EXPECT_EQ(kept[EventLog::kKeptHead - 1].text, std::to_string(EventLog::kKeptHead - 1));
  EXPECT_EQ(kept[EventLog::kKeptHead].text, std::to_string(EventLog::kKeptHead + 10'000));
  EXPECT_EQ(kept.back().text, std::to_string(total - 1));
}

TEST(EventLog, AReaderThatKeepsUpSeesEveryEventOnce) {
  EventLog log;
  std::size_t cursor = 0;
  std::size_t seen = 0, next = 0;
  for (std::size_t i = 0; i < 3 * (EventLog::kKeptHead + EventLog::kKeptTail); ++i) {
    log.post(0, i, "warning", std::to_string(i));
    if (i % 100 == 99) {
      for (const auto& e : log.since(cursor)) {
        ASSERT_EQ(e.kind, "warning");
        ASSERT_EQ(e.text, std::to_string(next++));
        ++seen;
      }
    }
  }
  for (const auto& e : log.since(cursor)) {
    ASSERT_EQ(e.text, std::to_string(next++));
    ++seen;
  }
  EXPECT_EQ(seen, log.posted());
  EXPECT_TRUE(log.since(cursor).empty());
}

TEST(EventLog, AReaderThatFellBehindIsToldHowManyItMissed) {
  EventLog log;
  std::size_t cursor = 0;
  const std::size_t total = EventLog::kKeptHead + EventLog::kKeptTail + 500;
  for (std::size_t i = 0; i < total; ++i) log.post(0, i, "warning", std::to_string(i));
  const auto got = log.since(cursor);
  ASSERT_EQ(got.size(), EventLog::kKeptHead + 1 + EventLog::kKeptTail);
  EXPECT_EQ(got[EventLog::kKeptHead - 1].text, std::to_string(EventLog::kKeptHead - 1));
  EXPECT_EQ(got[EventLog::kKeptHead].kind, "dropped");
  EXPECT_NE(got[EventLog::kKeptHead].text.find("500 events"), std::string::npos) << got[EventLog::kKeptHead].text;
  EXPECT_EQ(got[EventLog::kKeptHead + 1].text, std::to_string(EventLog::kKeptHead + 500));
  EXPECT_EQ(got.back().text, std::to_string(total - 1));
  EXPECT_EQ(cursor, total);
}

TEST(EventLog, MemoryIsBoundedByTheCaps) {
  // The worst case of the hostile flood: every event at the text cap. What is kept is at most
  // (head + tail) x (text cap + kind cap) bytes of text, whatever the number posted.
  EventLog log;
  for (int i = 0; i < 20'000; ++i) log.post(0, 0, std::string(500, 'k'), std::string(30'000, 'v'));
  std::size_t bytes = 0;
  for (const auto& e : log.snapshot()) bytes += e.text.size() + e.kind.size();
  EXPECT_LE(bytes, (EventLog::kKeptHead + EventLog::kKeptTail) * (EventLog::kMaxTextBytes + EventLog::kMaxKindBytes));
  EXPECT_EQ(log.posted(), 20'000u);
}

}  // namespace
