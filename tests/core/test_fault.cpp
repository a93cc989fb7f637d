// The fault-injection hook SOFTCONTACT_FAULT (include/softcontact/fault.hpp,
// docs/reliability.md "Fault injection"): what a value means, when it fires, and the
// message a bad value gets (an InputError, exit status 2).
#include <gtest/gtest.h>

#include <string>

#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"

using namespace softcontact;
using fault::Point;

namespace {

std::string refusal(const char* value, int rank = 0, int size = 1) {
  try {
    fault::configure(value, rank, size);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Fault, UnsetOrEmptyArmsNothing) {
  fault::configure(nullptr, 0, 1);
  EXPECT_FALSE(fault::hit(Point::step, 1000000));
  fault::configure("", 0, 1);
  EXPECT_FALSE(fault::hit(Point::frame_write, 1000000));
}

TEST(Fault, FiresOnceAtItsPointFromItsStepOn) {
  fault::configure("ioerror:frame_write:100", 0, 1);
  EXPECT_FALSE(fault::hit(Point::frame_write, 90));       // before the step
  EXPECT_FALSE(fault::hit(Point::checkpoint_write, 110));  // another point
  EXPECT_TRUE(fault::hit(Point::frame_write, 110));        // the first frame write at or after 100
  EXPECT_FALSE(fault::hit(Point::frame_write, 120));       // once
  fault::configure("nan:step:7", 0, 1);
  EXPECT_FALSE(fault::hit(Point::step, 6));
  EXPECT_TRUE(fault::hit(Point::step, 7));
  fault::configure(nullptr, 0, 1);
}

TEST(Fault, FiresOnlyOnItsRank) {
  fault::configure("ioerror:checkpoint_rename:5:1", 0, 3);
  EXPECT_FALSE(fault::hit(Point::checkpoint_rename, 5));
  fault::configure("ioerror:checkpoint_rename:5:1", 1, 3);
  EXPECT_TRUE(fault::hit(Point::checkpoint_rename, 5));
  fault::configure("ioerror:checkpoint_renamed:5:all", 2, 3);
  EXPECT_TRUE(fault::hit(Point::checkpoint_renamed, 5));
  fault::configure(nullptr, 0, 1);
}

TEST(Fault, BadValuesAreInputErrorsThatSayWhatWasExpected) {
  const std::string expected = "(expected ACTION:POINT:STEP[:RANK]";
  for (const char* v : {"kill", "kill:step", "kill:step:1:0:0", "kill:step:1:", "boom:step:1", "kill:frame:1",
                        "kill:step:-1", "kill:step:1x", "kill:step:1:first", "nan:frame_write:1",
                        "ioerror:step:1", "kill:step:1:3"}) {
    const std::string m = refusal(v, 0, 3);
    EXPECT_NE(m.find(std::string("SOFTCONTACT_FAULT='") + v + "'"), std::string::npos) << v << ": " << m;
    EXPECT_NE(m.find(expected), std::string::npos) << v << ": " << m;
  }
  EXPECT_NE(refusal("boom:step:1").find("unknown action 'boom' (one of kill, sigterm, sigint, ioerror, nan)"),
            std::string::npos);
  EXPECT_NE(refusal("kill:frame:1").find("unknown point 'frame' (one of step, frame_write"), std::string::npos);
  EXPECT_NE(refusal("kill:step:1:3", 0, 3).find("rank 3, but the job has 3 rank(s)"), std::string::npos);
  EXPECT_NE(refusal("nan:frame_write:1").find("'nan' applies at the point 'step' only"), std::string::npos);
  EXPECT_FALSE(fault::hit(Point::step, 1000000));  // a refused value arms nothing
}
