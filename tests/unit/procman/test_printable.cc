// Untrusted text on the operator's terminal: controls escaped, UTF-8 kept, long names cut.
#include <gtest/gtest.h>

#include "thicket/procman/printable.h"

namespace thicket::procman {
namespace {

TEST(Printable, EscapesControlsAndKeepsTextTabsAndUtf8) {
  EXPECT_EQ(printable("plain text\twith a tab"), "plain text\twith a tab");
  EXPECT_EQ(printable("\x1b[2Jcleared\r\n"), "\\x1b[2Jcleared\\x0d\\x0a");
  EXPECT_EQ(printable(std::string("nul\0del\x7f", 8)), "nul\\x00del\\x7f");
  EXPECT_EQ(printable("caf\xc3\xa9 \xe2\x86\x92 ok"), "caf\xc3\xa9 \xe2\x86\x92 ok");
  // U+009B (CSI) in UTF-8: a terminal may take it as ESC [.
  EXPECT_EQ(printable("\xc2\x9b"
                      "2J"),
            "\\xc2\\x9b2J");
}

TEST(Printable, ShortCutsAtACharacterBoundaryAndGivesTheLength) {
  EXPECT_EQ(printableShort("short"), "short");
  EXPECT_EQ(printableShort(std::string(100, 'a'), 10), "aaaaaaaaaa... (100 bytes)");
  // A cut inside the 2-byte é moves back before it.
  EXPECT_EQ(printableShort("abcdefghi\xc3\xa9xyz", 10), "abcdefghi... (14 bytes)");
}

}  // namespace
}  // namespace thicket::procman
