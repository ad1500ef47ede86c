#include "superdyna/io/text_table.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::io {
namespace {

using test::ScratchDir;
using test::writeFile;

TEST(TextTable, ForEachTextRowVisitsWhatReadTextRowsReturnsInOrder) {
  const ScratchDir dir("text_table");
  const auto file = dir.path() / "rows.csv";
  writeFile(file, "#timestamp,a,b\n1, 2.5 ,x\n\n  # comment\n4,5,z,extra\n3,,y\n");
  std::vector<TextRow> visited;
  forEachTextRow(file, Delimiter::kComma, [&visited](const TextRow& row) {
    visited.push_back(row);
    return true;
  });
  ASSERT_EQ(visited.size(), 3u);
  EXPECT_EQ(visited[0].line, 2);
  EXPECT_EQ(visited[0].fields, (std::vector<std::string>{"1", "2.5", "x"}));
  EXPECT_EQ(visited[1].line, 5);
  EXPECT_EQ(visited[1].text, "4,5,z,extra");
  EXPECT_EQ(visited[1].fields.size(), 4u);
  EXPECT_EQ(visited[2].line, 6);
  // A shorter row after a longer one keeps none of its fields (the row object is reused).
  EXPECT_EQ(visited[2].fields, (std::vector<std::string>{"3", "", "y"}));

  const std::vector<TextRow> all = readTextRows(file, Delimiter::kComma);
  ASSERT_EQ(all.size(), visited.size());
  for (std::size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(all[i].line, visited[i].line);
    EXPECT_EQ(all[i].fields, visited[i].fields);
  }
}

TEST(TextTable, ForEachTextRowStopsWhenTheVisitorSaysSo) {
  const ScratchDir dir("text_table");
  const auto file = dir.path() / "rows.txt";
  writeFile(file, "a b\nc d\ne f\n");
  int visits = 0;
  forEachTextRow(file, Delimiter::kWhitespace, [&visits](const TextRow& row) {
    ++visits;
    return row.fields[0] != "c";
  });
  EXPECT_EQ(visits, 2);
}

TEST(TextTable, AMissingFileIsAnErrorNamingIt) {
  const ScratchDir dir("text_table");
  const auto file = dir.path() / "absent.csv";
  try {
    forEachTextRow(file, Delimiter::kComma, [](const TextRow&) { return true; });
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot open file"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace superdyna::io
