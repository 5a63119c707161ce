// core: the one enum <-> string convention (core/enum_names.hpp), and the tables that use it.
#include <gtest/gtest.h>

#include <fstream>

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/scene.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/mapping/online.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition_3d.hpp"
#include "sonar3d/recon/deconvolve.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/world/change.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;

namespace demo {
// An enum naming its table for to_string / parse_enum<E>(text, what), as docs/design.md shows.
enum class Fruit { Apple, Pear, Quince };
inline constexpr const char* kFruitNames[] = {"apple", "pear", "quince"};  // by Fruit
constexpr const auto& enum_names(Fruit) { return kFruitNames; }
// Nested in a struct: the table named by a friend.
struct Basket {
  enum class Size { Small, Large };
  static constexpr const char* kSizeNames[] = {"small", "large"};
  friend constexpr const auto& enum_names(Size) { return kSizeNames; }
};
}  // namespace demo

TEST(EnumNames, RoundTripThroughTheTable) {
  for (const demo::Fruit f : {demo::Fruit::Apple, demo::Fruit::Pear, demo::Fruit::Quince}) {
    EXPECT_EQ(parse_enum<demo::Fruit>(to_string(f), "--fruit"), f);
    EXPECT_EQ(parse_enum<demo::Fruit>(demo::kFruitNames, enum_name(demo::kFruitNames, f), "x"), f);
  }
  EXPECT_STREQ(to_string(demo::Fruit::Quince), "quince");
  EXPECT_STREQ(to_string(demo::Basket::Size::Large), "large");
  EXPECT_EQ(parse_enum<demo::Basket::Size>("small", "size"), demo::Basket::Size::Small);
  EXPECT_STREQ(enum_name(demo::kFruitNames, static_cast<demo::Fruit>(7)), "?");
}

TEST(EnumNames, UnknownNameListsTheChoicesAndNamesTheFlag) {
  try {
    parse_enum<demo::Fruit>("Apple", "--fruit");
    ADD_FAILURE() << "a name in the wrong case was accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "--fruit must be one of apple, pear or quince, got 'Apple'");
  }
  expect_error([] { parse_enum<demo::Basket::Size>("", "basket.size"); },
               "basket.size must be one of small or large, got ''");
  // Control bytes are not echoed as they are, and a long text is cut.
  expect_error([] { parse_enum<demo::Fruit>(std::string("a\nb\x01", 4), "f"); }, "got 'a?b?'");
  expect_error([] { parse_enum<demo::Fruit>(std::string(100, 'z'), "f"); },
               "got '" + std::string(64, 'z') + "...'");
}

// Every table converted to the convention round-trips, and its parse error lists its names.
template <class E, std::size_t N, class Parse, class Name>
void round_trip(const char* const (&names)[N], Parse parse, Name name, const std::string& list) {
  for (std::size_t k = 0; k < N; ++k) {
    const E e = static_cast<E>(k);
    EXPECT_EQ(parse(names[k]), e) << names[k];
    EXPECT_STREQ(name(e), names[k]);
  }
  expect_error([&] { parse("no-such-name"); }, list + ", got 'no-such-name'");
}

TEST(EnumNames, LibraryTablesRoundTrip) {
  round_trip<NavConvention>(kNavConventionNames, parse_nav_convention, nav_convention_name,
                            "navigation convention must be one of enu or ned");
  round_trip<HoloOceanBins>(kHoloOceanBinsNames, parse_holoocean_bins, holoocean_bins_name,
                            "sample or cell");
  round_trip<DeconvConfig::Mode>(DeconvConfig::kModeNames, DeconvConfig::parse_mode,
                                 DeconvConfig::mode_name, "passes, voxel or auto");
  round_trip<DeconvConfig::Beam>(DeconvConfig::kBeamNames, DeconvConfig::parse_beam,
                                 DeconvConfig::beam_name, "sinc, flat or sensor");
  round_trip<DeconvConfig::Kernel>(DeconvConfig::kKernelNames, DeconvConfig::parse_kernel,
                                   DeconvConfig::kernel_name,
                                   "plain, normal, occlusion or normal+occlusion");
  round_trip<SwathAdjustMethod>(
      kSwathAdjustMethodNames, swath_adjust_method_from_string,
      [](SwathAdjustMethod m) { return to_string(m); }, "consecutive, global or drift");
  const char* const kinds[] = {"structure", "pipeline", "terrain"};
  round_trip<ObjectKind>(
      kinds, object_kind_from_string, [](ObjectKind k) { return to_string(k); },
      "object kind must be one of structure, pipeline or terrain");
  // Tables without a name function: parse only.
  EXPECT_EQ(parse_aris_clock("sonar"), ArisClock::Sonar);
  EXPECT_EQ(parse_aris_nav_source("static"), ArisNavSource::Static);
  EXPECT_EQ(parse_oculus_gains("divide"), OculusGains::Divide);
  EXPECT_EQ(parse_oculus_clock("rate"), OculusClock::Rate);
  EXPECT_EQ(parse_report_color("height"), ReportColor::Height);
  expect_error([] { parse_aris_nav_source("gps"); }, "auto, header, file or static, got 'gps'");
  expect_error([] { parse_report_color("rainbow"); }, "error or height, got 'rainbow'");
}

// The tables kept beside their only converter: every value has its name, the names are those the
// files hold, and the parsers give the convention's error.
TEST(EnumNames, FileLocalTablesNameEveryValue) {
  EXPECT_STREQ(symmetry_name(Symmetry::None), "none");
  EXPECT_STREQ(symmetry_name(Symmetry::Half), "180");
  EXPECT_STREQ(symmetry_name(Symmetry::Full), "full");
  EXPECT_STREQ(subspace_test_name(SubspaceTest::None), "kept");
  EXPECT_STREQ(subspace_test_name(SubspaceTest::Occupancy), "occupancy");
  EXPECT_STREQ(object_status_name(ObjectStatus::Unchanged), "unchanged");
  EXPECT_STREQ(object_status_name(ObjectStatus::Uncertain), "uncertain");
  EXPECT_STREQ(colour_space_name(ColourSpace::Lab), "lab");
  EXPECT_STREQ(frame_drop_name(FrameDrop::None), "none");
  EXPECT_STREQ(frame_drop_name(FrameDrop::BadTime), "bad_time");
  EXPECT_STREQ(report_input_name(ReportInput::Sweep), "sweep");
  EXPECT_STREQ(report_input_name(ReportInput::Ply), "ply");
  for (auto k : {BeamPattern::Kind::Sinc, BeamPattern::Kind::Flat, BeamPattern::Kind::Table})
    EXPECT_EQ(BeamPattern::parse_kind(BeamPattern::kind_name(k)), k);
  expect_error([] { BeamPattern::parse_kind("cosine"); },
               "the beam pattern must be one of sinc, flat or table, got 'cosine'");
  const auto dir = test::temp_dir("symmetry");
  std::ofstream(dir / "cat.yaml") << "models:\n  - {name: box, reference: tank, symmetry: 90}\n";
  expect_error([&] { read_catalogue((dir / "cat.yaml").string()); },
               "must be one of none, 180 or full, got '90'");
}
