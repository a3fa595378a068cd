// The laser_clustering nodes on the bus: built by name with remaps and
// parameters, fed LineScan messages, stepped by the deterministic executor
// on sim time (no sleeps).
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include "laser_clustering/nodes/conversions.hpp"
#include "laser_clustering/nodes/nodes.hpp"
#include "laser_clustering/nodes/register.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
namespace bus = tinyline::bus;
using tinyline::geometry_msgs::msg::PointStamped;
using tinyline::sensor_msgs::msg::JointState;
using tinyline::tinyline_msgs::msg::AlignmentResult;
using tinyline::tinyline_msgs::msg::ExpectedTomatoes;
using tinyline::tinyline_msgs::msg::LineClusters;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::tinyline_msgs::msg::PedicelDetection;
using tinyline::tinyline_msgs::msg::PedicelLayout;
using tinyline::tinyline_msgs::msg::TrussRegistration;
using ::testing::HasSubstr;

namespace {

// The laser_clustering nodes on stepped sim time (bus/testing.hpp); `io`
// publishes inputs and receives outputs.
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&lc::register_nodes}) {}
  std::shared_ptr<bus::Node> add(const std::string& type, bus::NodeOptions o) {
    return NodeRig::add("laser_clustering", type, std::move(o));
  }
  /// The pedicel finder as most tests run it: the blade throat 12 cm ahead.
  void add_finder() {
    bus::NodeOptions o;
    o.name = "finder";
    o.param("scissor_centre_z_m", 0.12);
    add("pedicel_finder", o);
  }
};

std::unique_ptr<LineScan> to_msg(const lc::LineScan& s, double t_s) {
  auto m = std::make_unique<LineScan>();
  m->header.stamp = bus::Time::from_seconds(t_s).to_msg();
  m->header.frame_id = "laser";
  for (std::size_t i = 0; i < s.size(); ++i) {
    m->angles.push_back(static_cast<float>(s.angle_rad[i]));
    const bool valid = s.valid(i);
    m->distance_m.push_back(valid ? static_cast<float>(s.range_m[i]) : std::nanf(""));
    m->status.push_back(valid ? LineScan::STATUS_VALID : LineScan::STATUS_TOO_DARK);
    if (!s.reflectance.empty()) m->reflectance.push_back(static_cast<float>(s.reflectance[i]));
  }
  return m;
}

// Discs before a wall 40 cm away.
lc::test::SynthScan before_wall(const std::vector<lc::test::Disc>& discs, unsigned seed = 1) {
  lc::test::SynthParams sp;
  sp.wall_z_m = 0.40;
  sp.seed = seed;
  return lc::test::synth_scan(discs, sp);
}

lc::test::SynthScan pedicel_scene(double x, unsigned seed = 1) {
  return before_wall({{x, 0.13, 0.003, 6.0, 1}, {-0.08, 0.25, 0.03, 6.0, 2}}, seed);
}

}  // namespace

TEST(LaserClusteringNodes, AllFourAreRegistered) {
  bus::NodeRegistry r;
  lc::register_nodes(r);
  for (const char* t : {"line_clusterer", "pedicel_finder", "tomato_registration", "reflectance_clusterer",
                        "alignment_search", "pitch_sweep"}) {
    EXPECT_NE(r.find("laser_clustering", t), nullptr) << t;
  }
}

TEST(LaserClusteringNodes, LineClustererPublishesObjectsAndNotesBadScans) {
  Harness h;
  bus::NodeOptions o;
  o.name = "clusterer";
  o.remap("scan", "/laser/scan").remap("clusters", "/laser/clusters").param("objects_eps_m", 0.008);
  h.add("line_clusterer", o);
  auto& got = h.collect<LineClusters>("/laser/clusters", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("/laser/scan");
  const auto s = pedicel_scene(0.02);
  pub->publish(to_msg(s.scan, 1.0));
  auto broken = to_msg(s.scan, 1.1);
  broken->status.pop_back();
  pub->publish(std::move(broken));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  const auto& c = *got[0];
  EXPECT_EQ(c.header.frame_id, "laser");
  EXPECT_EQ(c.labels.size(), 256u);
  EXPECT_EQ(c.fate.size(), 256u);
  // The pedicel is one narrow object at x 2 cm.
  int narrow = 0;
  for (const auto& k : c.clusters) {
    if (std::abs(k.width_m - 0.006) < 0.0015 && std::abs(k.centroid_x_m - 0.02) < 0.002) ++narrow;
  }
  EXPECT_EQ(narrow, 1);
  EXPECT_TRUE(got[1]->clusters.empty());
  EXPECT_THAT(got[1]->note, HasSubstr("255 statuses"));
}

TEST(LaserClusteringNodes, PedicelFinderReportsTheMoveAndHonoursTheExpectation) {
  Harness h;
  h.add_finder();
  auto& got = h.collect<PedicelDetection>("pedicel", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto expected = h.io->create_publisher<PointStamped>("expected_pedicel");

  pub->publish(to_msg(pedicel_scene(0.025).scan, 1.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0]->outcome, PedicelDetection::MOVE) << got[0]->reason;
  EXPECT_NEAR(got[0]->lateral_offset_m, 0.025, 0.0015);
  EXPECT_GT(got[0]->confidence, 0.5);

  // Two pedicels; vision expects the one at +5 cm.
  const auto two = before_wall({{0.005, 0.12, 0.003, 6.0, 1}, {0.05, 0.12, 0.003, 6.0, 2}});
  auto p = std::make_unique<PointStamped>();
  p->header.stamp = bus::Time::from_seconds(1.95).to_msg();
  p->point.x = 0.048;
  p->point.z = 0.12;
  expected->publish(std::move(p));
  pub->publish(to_msg(two.scan, 2.0));
  // An hour later the expectation is stale: the throat rules again.
  pub->publish(to_msg(two.scan, 3600.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 3u);
  EXPECT_NEAR(got[1]->position.x, 0.05, 0.002);
  EXPECT_NEAR(got[2]->position.x, 0.005, 0.002);
  EXPECT_EQ(got[2]->outcome, PedicelDetection::CUT_HERE);

  // Nothing in range.
  lc::test::SynthParams far;
  far.wall_z_m = 1.5;
  pub->publish(to_msg(lc::test::synth_scan({}, far).scan, 4000.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 4u);
  EXPECT_EQ(got[3]->outcome, PedicelDetection::OUT_OF_VIEW);
  EXPECT_THAT(got[3]->reason, HasSubstr("no return between"));
}

TEST(LaserClusteringNodes, PedicelFinderTakesTheVisionsTrussLayout) {
  // The scene of PedicelFinder.TrussLayoutPicksTheTargetOverANearerNeighbour:
  // the nearer pedicel (-1 cm) wins on position alone; a layout that puts a
  // neighbour 5 cm to -x of the target makes the one at +4 cm the target.
  Harness h;
  h.add_finder();
  auto& got = h.collect<PedicelDetection>("pedicel", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto layout = h.io->create_publisher<PedicelLayout>("expected_layout");
  const auto two = before_wall({{-0.01, 0.12, 0.003, 6.0, 1}, {0.04, 0.12, 0.003, 6.0, 2}}, 4);
  auto make = [](double stamp_s) {
    auto l = std::make_unique<PedicelLayout>();
    l->header.stamp = bus::Time::from_seconds(stamp_s).to_msg();
    l->expected.z = 0.12;
    l->expected_sd_m = 0.03;  // the throat, off by up to a few cm
    l->neighbours.resize(1);
    l->neighbours[0].x = -0.05;
    l->neighbours[0].z = 0.12;
    l->may_be_absent = {false};
    return l;
  };

  pub->publish(to_msg(two.scan, 1.0));  // no layout yet
  h.ex.spin_until_idle();
  auto broken = make(1.9);
  broken->may_be_absent.clear();  // one neighbour, no flag: dropped whole
  layout->publish(std::move(broken));
  h.ex.spin_until_idle();
  pub->publish(to_msg(two.scan, 2.0));
  h.ex.spin_until_idle();
  layout->publish(make(2.9));
  h.ex.spin_until_idle();
  pub->publish(to_msg(two.scan, 3.0));
  pub->publish(to_msg(two.scan, 3600.0));  // stale again
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 4u);
  EXPECT_NEAR(got[0]->position.x, -0.01, 0.002) << "position alone: the nearer";
  EXPECT_NEAR(got[1]->position.x, -0.01, 0.002) << "the malformed layout is ignored";
  EXPECT_NEAR(got[2]->position.x, 0.04, 0.002) << "the layout picks the target";
  EXPECT_EQ(got[2]->outcome, PedicelDetection::MOVE);
  EXPECT_NEAR(got[3]->position.x, -0.01, 0.002) << "a stale layout is ignored";
}

namespace {

// What the node's scan conversion gives the core (float on the wire).
lc::LineScan through_the_wire(const lc::LineScan& s) {
  lc::LineScan out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    out.angle_rad.push_back(static_cast<float>(s.angle_rad[i]));
    out.range_m.push_back(s.valid(i) ? static_cast<double>(static_cast<float>(s.range_m[i]))
                                     : std::numeric_limits<double>::quiet_NaN());
    if (!s.reflectance.empty()) {
      out.reflectance.push_back(s.valid(i) ? static_cast<double>(static_cast<float>(s.reflectance[i]))
                                           : std::numeric_limits<double>::quiet_NaN());
    }
  }
  return out;
}

std::unique_ptr<PedicelLayout> layout_at(double stamp_s, double x, double z, double sd) {
  auto l = std::make_unique<PedicelLayout>();
  l->header.stamp = bus::Time::from_seconds(stamp_s).to_msg();
  l->header.frame_id = "laser";
  l->expected.x = x;
  l->expected.z = z;
  l->expected_sd_m = sd;
  return l;
}

}  // namespace

// The closed loop's runners-up on the bus: a PedicelLayout's alternatives
// reach the core as PedicelExpectation::alternatives, and the node answers
// what the core answers with the same expectation.
TEST(LaserClusteringNodes, PedicelFinderCarriesTheLayoutsRunnersUpToTheCore) {
  Harness h;
  h.add_finder();
  auto& got = h.collect<PedicelDetection>("pedicel", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto layout = h.io->create_publisher<PedicelLayout>("expected_layout");
  // Two pedicels; the expected point (-3 cm) is nearer the one at -1 cm, the
  // previous scan's runner-up sits on the one at +4 cm.
  const auto two = before_wall({{-0.01, 0.12, 0.003, 6.0, 1}, {0.04, 0.12, 0.003, 6.0, 2}}, 9);

  layout->publish(layout_at(0.9, -0.03, 0.12, 0.03));
  h.ex.spin_until_idle();
  pub->publish(to_msg(two.scan, 1.0));
  h.ex.spin_until_idle();
  auto with_runner_up = layout_at(1.9, -0.03, 0.12, 0.03);
  with_runner_up->alternatives.resize(1);
  with_runner_up->alternatives[0].x = 0.041;
  with_runner_up->alternatives[0].z = 0.121;
  with_runner_up->alternative_weights = {0.9};
  layout->publish(std::move(with_runner_up));
  h.ex.spin_until_idle();
  pub->publish(to_msg(two.scan, 2.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_NEAR(got[0]->position.x, -0.01, 0.002) << "without the runner-up: the one nearer the expected point";
  EXPECT_NEAR(got[1]->position.x, 0.04, 0.002) << "the runner-up's place wins";

  // The core with the same expectation, on the same (float) scan.
  lc::PedicelFinderParams fp;
  fp.scissors.centre_z_m = 0.12;
  lc::PedicelExpectation e{{-0.03, 0.12}, 0.03, {}, 0.015};
  e.alternatives.push_back({{0.041, 0.121}, 0.9});
  const auto scan = through_the_wire(two.scan);
  lc::LineScanClusterer clusterer;
  const auto core = lc::find_pedicel(scan, clusterer.run(scan), fp, e);
  const auto& node = *got[1];
  EXPECT_EQ(node.outcome, static_cast<std::uint8_t>(core.outcome)) << core.reason;
  EXPECT_EQ(node.reason, core.reason);
  EXPECT_EQ(node.cluster, core.cluster);
  EXPECT_DOUBLE_EQ(node.position.x, core.position_xz_m.x());
  EXPECT_DOUBLE_EQ(node.position.z, core.position_xz_m.y());
  EXPECT_DOUBLE_EQ(node.lateral_offset_m, core.lateral_offset_m);
  EXPECT_DOUBLE_EQ(node.confidence, core.confidence);
  EXPECT_EQ(node.num_candidates, core.candidates.size());
}

namespace {

void expect_same(const PedicelDetection& node, const lc::PedicelDetection& core) {
  EXPECT_EQ(node.outcome, static_cast<std::uint8_t>(core.outcome)) << core.reason;
  EXPECT_EQ(node.reason, core.reason);
  EXPECT_EQ(node.cluster, core.cluster);
  EXPECT_DOUBLE_EQ(node.position.x, core.position_xz_m.x());
  EXPECT_DOUBLE_EQ(node.position.z, core.position_xz_m.y());
  EXPECT_DOUBLE_EQ(node.lateral_offset_m, core.lateral_offset_m);
  EXPECT_DOUBLE_EQ(node.depth_offset_m, core.depth_offset_m);
  EXPECT_DOUBLE_EQ(node.confidence, core.confidence);
  ASSERT_EQ(node.candidates.size(), core.candidates.size());
  ASSERT_EQ(node.candidate_weights.size(), core.candidates.size());
  ASSERT_EQ(node.candidate_widths_m.size(), core.candidates.size());
  for (std::size_t k = 0; k < core.candidates.size(); ++k) {
    EXPECT_DOUBLE_EQ(node.candidates[k].x, core.candidates[k].position_xz_m.x()) << k;
    EXPECT_DOUBLE_EQ(node.candidates[k].z, core.candidates[k].position_xz_m.y()) << k;
    EXPECT_DOUBLE_EQ(node.candidate_weights[k], core.candidates[k].weight) << k;
    EXPECT_DOUBLE_EQ(node.candidate_widths_m[k], core.candidates[k].width_m) << k;
  }
}

}  // namespace

// The closed loop of 4.5 run by a controller on the bus: it reads the
// finder's detection (candidates and their weights), asks the core where to
// look after the move (expectation_after_centring, runners-up carried) and
// publishes that as the next layout; the finder's second answer is the
// core's own loop's.
TEST(LaserClusteringNodes, AControllerOnTheBusClosesTheLoopAsTheCoreDoes) {
  Harness h;
  h.add_finder();
  auto& got = h.collect<PedicelDetection>("pedicel", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto layout = h.io->create_publisher<PedicelLayout>("expected_layout");
  lc::PedicelFinderParams fp;
  fp.scissors.centre_z_m = 0.12;
  // Two pedicels 5 cm apart and a neighbour expected 5 cm to -x of the target.
  const std::vector<lc::test::Disc> truss{{-0.01, 0.125, 0.003, 6.0, 1}, {0.04, 0.12, 0.003, 6.0, 2}};
  lc::PedicelExpectation first{{-0.03, 0.12}, 0.03, {}, 0.015};
  first.neighbours.push_back({{-0.08, 0.12}, true});

  auto l1 = std::make_unique<PedicelLayout>();
  lc::to_msg(first, *l1);
  l1->header.stamp = bus::Time::from_seconds(0.95).to_msg();
  layout->publish(std::move(l1));
  h.ex.spin_until_idle();
  const auto scan1 = before_wall(truss, 17);
  pub->publish(to_msg(scan1.scan, 1.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  const auto s1 = through_the_wire(scan1.scan);
  lc::LineScanClusterer clusterer;
  const auto core1 = lc::find_pedicel(s1, clusterer.run(s1), fp, first);
  expect_same(*got[0], core1);
  ASSERT_EQ(core1.outcome, lc::PedicelOutcome::kMove) << core1.reason;
  ASSERT_GE(core1.candidates.size(), 2u) << "a runner-up to carry";

  // The controller: detection message -> core -> next layout message.
  lc::PedicelDetection seen;
  ASSERT_EQ(lc::from_msg(*got[0], seen), "");
  lc::PedicelExpectation before;
  {
    PedicelLayout echo;
    lc::to_msg(first, echo);
    ASSERT_EQ(lc::from_msg(echo, 0.015, before), "");
  }
  const auto next = lc::expectation_after_centring(fp, before, seen);
  const auto next_core = lc::expectation_after_centring(fp, first, core1);
  ASSERT_EQ(next.alternatives.size(), next_core.alternatives.size());
  ASSERT_FALSE(next.alternatives.empty());
  for (std::size_t k = 0; k < next.alternatives.size(); ++k) {
    EXPECT_EQ(next.alternatives[k].position_xz_m, next_core.alternatives[k].position_xz_m);
    EXPECT_DOUBLE_EQ(next.alternatives[k].weight, next_core.alternatives[k].weight);
  }
  EXPECT_EQ(next.position_xz_m, next_core.position_xz_m);
  ASSERT_EQ(next.neighbours.size(), 1u);
  EXPECT_EQ(next.neighbours[0].position_xz_m, next_core.neighbours[0].position_xz_m);
  auto l2 = std::make_unique<PedicelLayout>();
  lc::to_msg(next, *l2);
  l2->header.stamp = bus::Time::from_seconds(1.95).to_msg();
  layout->publish(std::move(l2));
  h.ex.spin_until_idle();

  // The gripper made the move: the truss is now where the move put it.
  const Eigen::Vector2d move = core1.position_xz_m - Eigen::Vector2d(fp.scissors.centre_x_m, fp.scissors.centre_z_m);
  std::vector<lc::test::Disc> moved = truss;
  for (auto& d : moved) {
    d.x_m -= move.x();
    d.z_m -= move.y();
  }
  const auto scan2 = before_wall(moved, 18);
  pub->publish(to_msg(scan2.scan, 2.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  const auto s2 = through_the_wire(scan2.scan);
  expect_same(*got[1], lc::find_pedicel(s2, clusterer.run(s2), fp, next_core));
}

// The conversions a controller uses: a layout and a detection survive the
// trip through their messages, and a malformed detection says what is wrong.
TEST(LaserClusteringNodes, PedicelMessagesRoundTripAndNameWhatIsWrong) {
  lc::PedicelExpectation e{{0.01, 0.13}, 0.012, {}, 0.02};
  e.neighbours.push_back({{-0.05, 0.12}, false});
  e.neighbours.push_back({{0.06, 0.14}, true});
  e.alternatives.push_back({{0.03, 0.125}, 0.4});
  e.gate_sd = 4.0;
  PedicelLayout l;
  lc::to_msg(e, l);
  lc::PedicelExpectation back;
  ASSERT_EQ(lc::from_msg(l, 0.5, back), "");
  EXPECT_EQ(back.position_xz_m, e.position_xz_m);
  EXPECT_DOUBLE_EQ(back.sd_m, 0.012);
  EXPECT_DOUBLE_EQ(back.neighbour_sd_m, 0.02);
  ASSERT_EQ(back.neighbours.size(), 2u);
  EXPECT_EQ(back.neighbours[1].position_xz_m, e.neighbours[1].position_xz_m);
  EXPECT_TRUE(back.neighbours[1].may_be_absent);
  ASSERT_EQ(back.alternatives.size(), 1u);
  EXPECT_DOUBLE_EQ(back.alternatives[0].weight, 0.4);
  EXPECT_DOUBLE_EQ(back.gate_sd, 4.0);
  e.gate_sd = std::numeric_limits<double>::infinity();
  lc::to_msg(e, l);
  EXPECT_DOUBLE_EQ(l.gate_sd, 0.0) << "no gate goes on the wire as 0";
  ASSERT_EQ(lc::from_msg(l, 0.5, back), "");
  EXPECT_TRUE(std::isinf(back.gate_sd));
  l.alternative_weights[0] = 2.0;
  EXPECT_THAT(lc::from_msg(l, 0.5, back), HasSubstr("alternative 0 has weight 2"));
  EXPECT_TRUE(std::isinf(back.gate_sd)) << "a bad layout leaves the expectation alone";

  lc::PedicelDetection d;
  d.outcome = lc::PedicelOutcome::kMove;
  d.reason = "moved";
  d.cluster = 3;
  d.position_xz_m = {0.02, 0.13};
  d.candidates.resize(2);
  d.candidates[0].position_xz_m = {0.02, 0.13};
  d.candidates[0].weight = 0.6;
  d.candidates[0].width_m = 0.006;
  d.candidates[1].position_xz_m = {-0.04, 0.12};
  d.candidates[1].weight = 0.2;
  d.candidates[1].width_m = 0.007;
  PedicelDetection m;
  lc::to_msg(d, m);
  EXPECT_EQ(m.num_candidates, 2u);
  lc::PedicelDetection dd;
  ASSERT_EQ(lc::from_msg(m, dd), "");
  EXPECT_EQ(dd.outcome, lc::PedicelOutcome::kMove);
  EXPECT_EQ(dd.cluster, 3);
  ASSERT_EQ(dd.candidates.size(), 2u);
  EXPECT_EQ(dd.candidates[1].position_xz_m, d.candidates[1].position_xz_m);
  EXPECT_DOUBLE_EQ(dd.candidates[1].weight, 0.2);
  EXPECT_DOUBLE_EQ(dd.candidates[1].width_m, 0.007);
  m.candidate_widths_m.pop_back();
  EXPECT_THAT(lc::from_msg(m, dd), HasSubstr("2 candidates but 2 candidate_weights and 1 candidate_widths_m"));
  m.outcome = 9;
  EXPECT_THAT(lc::from_msg(m, dd), HasSubstr("unknown outcome 9"));
}

// A layout sure of itself (registered on the tomatoes) gates: a pedicel far
// from it is nothing to cut, not a move; gate_sd 0 is no gate; a bad
// runner-up or gate drops the layout whole, with what and where.
TEST(LaserClusteringNodes, PedicelFinderGatesOnTheLayoutAndDropsABadOne) {
  Harness h;
  h.add_finder();
  auto& got = h.collect<PedicelDetection>("pedicel", bus::QoS::keep_last(20));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto layout = h.io->create_publisher<PedicelLayout>("expected_layout");
  const auto far = before_wall({{0.06, 0.125, 0.003, 6.0, 1}}, 21);
  double t = 1.0;
  auto detect = [&](std::unique_ptr<PedicelLayout> l) {
    l->header.stamp = bus::Time::from_seconds(t - 0.05).to_msg();
    layout->publish(std::move(l));
    h.ex.spin_until_idle();
    pub->publish(to_msg(far.scan, t));
    h.ex.spin_until_idle();
    t += 1.0;
    return got.back();
  };

  auto gated = layout_at(0, 0.0, 0.12, 0.012);
  gated->gate_sd = 4.0;  // 4.8 cm: the pedicel is 6 cm off
  const auto g = detect(std::move(gated));
  EXPECT_EQ(g->outcome, PedicelDetection::NOTHING_TO_CUT) << g->reason;
  EXPECT_THAT(g->reason, HasSubstr("none within 0.048 m"));
  EXPECT_EQ(g->num_candidates, 0u);

  const auto open = detect(layout_at(0, 0.0, 0.12, 0.012));  // gate_sd 0: no gate
  EXPECT_EQ(open->outcome, PedicelDetection::MOVE) << open->reason;
  EXPECT_NEAR(open->position.x, 0.06, 0.002);

  // A runner-up near the pedicel opens the gate there.
  auto alt = layout_at(0, 0.0, 0.12, 0.012);
  alt->gate_sd = 4.0;
  alt->alternatives.resize(1);
  alt->alternatives[0].x = 0.055;
  alt->alternatives[0].z = 0.125;
  alt->alternative_weights = {0.5};
  EXPECT_EQ(detect(std::move(alt))->outcome, PedicelDetection::MOVE);

  // Malformed layouts are dropped whole: the previous (gated, opened by its
  // runner-up) one still counts, and the warning says what and where.
  struct Bad {
    std::function<void(PedicelLayout&)> spoil;
    const char* says;
  };
  const std::vector<Bad> bad{
      {[](PedicelLayout& l) { l.alternative_weights.clear(); }, "1 alternatives but 0 alternative_weights"},
      {[](PedicelLayout& l) { l.alternative_weights[0] = 1.5; }, "alternative 0 has weight 1.5"},
      {[](PedicelLayout& l) { l.alternative_weights[0] = 0.0; }, "alternative 0 has weight 0"},
      {[](PedicelLayout& l) { l.alternatives[0].z = std::nan(""); }, "alternative 0 is not finite"},
      {[](PedicelLayout& l) { l.gate_sd = -1.0; }, "gate_sd must be finite and >= 0"},
      {[](PedicelLayout& l) { l.gate_sd = std::nan(""); }, "gate_sd must be finite and >= 0"},
  };
  for (const auto& b : bad) {
    auto l = layout_at(0, 0.0, 0.12, 0.012);
    l->alternatives.resize(1);
    l->alternatives[0].x = -0.03;
    l->alternatives[0].z = 0.12;
    l->alternative_weights = {0.5};
    b.spoil(*l);
    // Dropped: the runner-up-opened gate of the last good layout still lets
    // the pedicel through (a spoiled one taken would gate it out or fail).
    const auto d = detect(std::move(l));
    EXPECT_EQ(d->outcome, PedicelDetection::MOVE) << b.says << ": " << d->reason;
    EXPECT_TRUE(h.log->contains(bus::LogLevel::Warn, b.says)) << b.says;
  }
  EXPECT_TRUE(h.log->contains(bus::LogLevel::Warn, "expected_layout (stamp"));
  EXPECT_TRUE(h.log->contains(bus::LogLevel::Warn, "frame 'laser') ignored"));
}

namespace {

// The tomato look (tomato_registration_test's truss): four tomatoes, each
// its own size and depth, cut 1 cm below their centres; the vision sees them
// all moved by -offset, each off by its own few millimetres.
const std::vector<lc::test::Disc> kTruss{{-0.11, 0.23, 0.028, 6.0, 1}, {-0.04, 0.21, 0.033, 6.0, 2},
                                         {0.035, 0.24, 0.026, 6.0, 3}, {0.10, 0.22, 0.031, 6.0, 4}};

lc::test::SynthScan truss_scan(unsigned seed) {
  lc::test::SynthParams sp;
  sp.wall_z_m = 0.45;
  sp.noise_sd_m = 0.003;
  sp.seed = seed;
  return lc::test::synth_scan(kTruss, sp);
}

std::vector<lc::ExpectedTomato> vision_tomatoes(const Eigen::Vector2d& offset) {
  const double height = 0.01;
  const double jitter[][2] = {{0.002, -0.003}, {-0.003, 0.001}, {0.001, 0.003}, {-0.002, -0.002}};
  std::vector<lc::ExpectedTomato> out;
  for (std::size_t i = 0; i < kTruss.size(); ++i) {
    const auto& d = kTruss[i];
    out.push_back({Eigen::Vector3d(d.x_m - offset.x() + jitter[i][0], height, d.z_m - offset.y() + jitter[i][1]),
                   std::sqrt(d.radius_m * d.radius_m + height * height)});
  }
  return out;
}

std::unique_ptr<ExpectedTomatoes> tomatoes_msg(const std::vector<lc::ExpectedTomato>& t, double stamp_s,
                                               const std::string& frame = "laser") {
  auto m = std::make_unique<ExpectedTomatoes>();
  m->header.stamp = bus::Time::from_seconds(stamp_s).to_msg();
  m->header.frame_id = frame;
  for (const auto& e : t) {
    m->centres.emplace_back();
    m->centres.back().x = e.centre_m.x();
    m->centres.back().y = e.centre_m.y();
    m->centres.back().z = e.centre_m.z();
    m->radii_m.push_back(e.radius_m);
  }
  return m;
}

std::size_t warnings_with(const bus::CaptureSink& log, std::string_view needle) {
  std::size_t n = 0;
  for (const auto& r : log.records()) n += r.level == bus::LogLevel::Warn && r.text.find(needle) != std::string::npos;
  return n;
}

struct TomatoLook {
  Harness h;
  std::shared_ptr<lc::TomatoRegistrationNode> node;
  std::vector<std::shared_ptr<const TrussRegistration>>& got =
      h.collect<TrussRegistration>("truss_registration", bus::QoS::keep_last(20));
  std::shared_ptr<bus::Publisher<LineScan>> scan = h.io->create_publisher<LineScan>("scan");
  std::shared_ptr<bus::Publisher<ExpectedTomatoes>> tomatoes =
      h.io->create_publisher<ExpectedTomatoes>("expected_tomatoes");

  explicit TomatoLook(bus::NodeOptions o = {}) {
    o.name = "look";
    node = std::dynamic_pointer_cast<lc::TomatoRegistrationNode>(h.add("tomato_registration", std::move(o)));
  }
  void send(std::unique_ptr<ExpectedTomatoes> t) {
    tomatoes->publish(std::move(t));
    h.ex.spin_until_idle();
  }
  void send(std::unique_ptr<LineScan> s) {
    scan->publish(std::move(s));
    h.ex.spin_until_idle();
  }
};

}  // namespace

// The node's registration is the core's on the same scan and tomatoes.
TEST(LaserClusteringNodes, TomatoRegistrationAnswersWhatTheCoreAnswers) {
  TomatoLook look;
  ASSERT_NE(look.node, nullptr);
  const Eigen::Vector2d offset(0.03, -0.015);
  const auto s = truss_scan(11);
  look.send(tomatoes_msg(vision_tomatoes(offset), 0.95));
  look.send(to_msg(s.scan, 1.0));
  ASSERT_EQ(look.got.size(), 1u);
  const auto& r = *look.got[0];
  EXPECT_EQ(r.header.frame_id, "laser");
  EXPECT_EQ(bus::Time::from_msg(r.header.stamp), bus::Time::from_seconds(1.0));
  EXPECT_EQ(bus::Time::from_msg(r.expected_stamp), bus::Time::from_seconds(0.95));
  ASSERT_TRUE(r.ok) << r.reason;
  EXPECT_NEAR(r.shift_x_m, offset.x(), 0.004);
  EXPECT_NEAR(r.shift_z_m, offset.y(), 0.004);

  const auto core = lc::register_tomatoes(through_the_wire(s.scan), vision_tomatoes(offset));
  EXPECT_EQ(r.ok, core.ok);
  EXPECT_EQ(r.reason, core.reason);
  EXPECT_DOUBLE_EQ(r.shift_x_m, core.shift_xz_m.x());
  EXPECT_DOUBLE_EQ(r.shift_z_m, core.shift_xz_m.y());
  EXPECT_EQ(r.tomatoes_in_plane, core.tomatoes_in_plane);
  EXPECT_EQ(r.tomatoes_matched, core.tomatoes_matched);
  EXPECT_EQ(r.inliers, core.inliers);
  EXPECT_DOUBLE_EQ(r.rms_m, core.rms_m);
  EXPECT_DOUBLE_EQ(r.support, core.support);
  EXPECT_DOUBLE_EQ(r.runner_up_support, core.runner_up_support);
  EXPECT_EQ(r.violations, core.violations);
  EXPECT_DOUBLE_EQ(r.runner_up_shift_x_m, core.runner_up_shift_xz_m.x());
  EXPECT_DOUBLE_EQ(r.runner_up_shift_z_m, core.runner_up_shift_xz_m.y());

  // The same tomatoes serve the next scan of their frame too.
  look.send(to_msg(s.scan, 1.5));
  ASSERT_EQ(look.got.size(), 2u);
  EXPECT_DOUBLE_EQ(look.got[1]->shift_x_m, core.shift_xz_m.x());
  EXPECT_EQ(look.node->scans_without_tomatoes(), 0u);

  // The caller's search bound replaces the node's (that it reaches the
  // core: TomatoRegistrationAnswersBadInputWithAReason's too_narrow).
  auto narrow = tomatoes_msg(vision_tomatoes(offset), 1.95);
  narrow->max_shift_m = 0.02;
  look.send(std::move(narrow));
  look.send(to_msg(s.scan, 2.0));
  ASSERT_EQ(look.got.size(), 3u);
  lc::TomatoRegistrationParams p;
  p.max_shift_m = 0.02;
  const auto bounded = lc::register_tomatoes(through_the_wire(s.scan), vision_tomatoes(offset), p);
  EXPECT_EQ(look.got[2]->ok, bounded.ok);
  EXPECT_EQ(look.got[2]->reason, bounded.reason);
  EXPECT_DOUBLE_EQ(look.got[2]->shift_x_m, bounded.shift_xz_m.x());
  EXPECT_DOUBLE_EQ(look.got[2]->shift_z_m, bounded.shift_xz_m.y());
  EXPECT_DOUBLE_EQ(look.got[2]->support, bounded.support);
}

// A scan with no tomatoes of its frame and age asked nothing: no answer,
// counted, and each cause warned about once.
TEST(LaserClusteringNodes, TomatoRegistrationCountsScansWithoutTomatoesAndWarnsOnce) {
  TomatoLook look;
  const auto s = truss_scan(12);
  look.send(to_msg(s.scan, 1.0));
  look.send(to_msg(s.scan, 1.1));
  EXPECT_TRUE(look.got.empty());
  EXPECT_EQ(look.node->scans_without_tomatoes(), 2u);
  EXPECT_EQ(warnings_with(*look.h.log, "no expected_tomatoes received yet"), 1u);

  look.send(tomatoes_msg(vision_tomatoes({0.0, 0.0}), 1.15, "camera"));  // the vision forgot to transform them
  look.send(to_msg(s.scan, 1.2));
  look.send(to_msg(s.scan, 1.3));
  EXPECT_TRUE(look.got.empty());
  EXPECT_EQ(look.node->scans_without_tomatoes(), 4u);
  EXPECT_EQ(warnings_with(*look.h.log, "the expected_tomatoes are in frame 'camera', the scan in 'laser'"), 1u);

  look.send(tomatoes_msg(vision_tomatoes({0.0, 0.0}), 1.25));
  look.send(to_msg(s.scan, 1.4));
  ASSERT_EQ(look.got.size(), 1u);
  EXPECT_TRUE(look.got[0]->ok) << look.got[0]->reason;
  look.send(to_msg(s.scan, 5.0));  // the gripper has long moved on
  look.send(to_msg(s.scan, 6.0));
  EXPECT_EQ(look.got.size(), 1u);
  EXPECT_EQ(look.node->scans_without_tomatoes(), 6u);
  EXPECT_EQ(warnings_with(*look.h.log, "expectation_max_age_s 1)"), 1u);
}

// Bad tomatoes and bad scans get a registration that says what is wrong and
// where; a good message afterwards registers again.
TEST(LaserClusteringNodes, TomatoRegistrationAnswersBadInputWithAReason) {
  TomatoLook look;
  const auto s = truss_scan(13);
  const auto good = vision_tomatoes({0.0, 0.0});
  auto nan_radius = tomatoes_msg(good, 1.0);
  nan_radius->radii_m[1] = std::nan("");
  look.send(std::move(nan_radius));
  look.send(to_msg(s.scan, 1.0));
  ASSERT_EQ(look.got.size(), 1u);
  EXPECT_FALSE(look.got[0]->ok);
  EXPECT_THAT(look.got[0]->reason, HasSubstr("expected_tomatoes malformed: tomato 1 has radius nan"));
  EXPECT_EQ(warnings_with(*look.h.log, "tomato 1 has radius nan"), 1u);

  auto negative = tomatoes_msg(good, 2.0);
  negative->radii_m[0] = -0.03;
  look.send(std::move(negative));
  look.send(to_msg(s.scan, 2.0));
  ASSERT_EQ(look.got.size(), 2u);
  EXPECT_THAT(look.got[1]->reason, HasSubstr("tomato 0 has radius -0.03"));

  auto nan_centre = tomatoes_msg(good, 3.0);
  nan_centre->centres[2].z = std::nan("");
  look.send(std::move(nan_centre));
  look.send(to_msg(s.scan, 3.0));
  ASSERT_EQ(look.got.size(), 3u);
  EXPECT_THAT(look.got[2]->reason, HasSubstr("tomato 2 has a non-finite centre"));

  auto short_radii = tomatoes_msg(good, 4.0);
  short_radii->radii_m.pop_back();
  look.send(std::move(short_radii));
  look.send(to_msg(s.scan, 4.0));
  ASSERT_EQ(look.got.size(), 4u);
  EXPECT_THAT(look.got[3]->reason, HasSubstr("4 centres but 3 radii_m"));

  auto negative_bound = tomatoes_msg(good, 4.5);
  negative_bound->max_shift_m = -0.01;
  look.send(std::move(negative_bound));
  look.send(to_msg(s.scan, 4.5));
  ASSERT_EQ(look.got.size(), 5u);
  EXPECT_THAT(look.got[4]->reason, HasSubstr("max_shift_m must be finite and >= 0"));
  look.got.pop_back();

  auto too_narrow = tomatoes_msg(good, 4.6);  // finer than the node's grid step: the core says so
  too_narrow->max_shift_m = 0.001;
  look.send(std::move(too_narrow));
  look.send(to_msg(s.scan, 4.6));
  ASSERT_EQ(look.got.size(), 5u);
  EXPECT_FALSE(look.got[4]->ok);
  EXPECT_THAT(look.got[4]->reason, HasSubstr("grid_step_m must be in (0, max_shift_m]"));
  look.got.pop_back();

  look.send(tomatoes_msg({}, 5.0));  // the vision saw none: the core's answer
  look.send(to_msg(s.scan, 5.0));
  ASSERT_EQ(look.got.size(), 5u);
  EXPECT_FALSE(look.got[4]->ok);
  EXPECT_THAT(look.got[4]->reason, HasSubstr("cut by the laser plane"));

  look.send(tomatoes_msg(good, 6.0));
  auto broken = to_msg(s.scan, 6.0);
  broken->status.pop_back();
  look.send(std::move(broken));
  ASSERT_EQ(look.got.size(), 6u);
  EXPECT_FALSE(look.got[5]->ok);
  EXPECT_THAT(look.got[5]->reason, HasSubstr("255 statuses"));

  auto dark = to_msg(s.scan, 6.1);  // every pixel invalid
  for (auto& st : dark->status) st = LineScan::STATUS_TOO_DARK;
  look.send(std::move(dark));
  ASSERT_EQ(look.got.size(), 7u);
  EXPECT_FALSE(look.got[6]->ok);
  EXPECT_THAT(look.got[6]->reason, HasSubstr("no return"));

  look.send(to_msg(s.scan, 6.2));
  ASSERT_EQ(look.got.size(), 8u);
  EXPECT_TRUE(look.got[7]->ok) << look.got[7]->reason;
  EXPECT_EQ(look.node->scans_without_tomatoes(), 0u);
}

TEST(LaserClusteringNodes, TomatoRegistrationRejectsBadParametersAtStart) {
  Harness h;
  auto expect_error = [&](bus::NodeOptions o, const char* says) {
    o.name = "look";
    try {
      h.add("tomato_registration", o);
      ADD_FAILURE() << "expected a ParamError saying " << says;
    } catch (const bus::ParamError& e) {
      EXPECT_THAT(e.what(), HasSubstr(says));
    }
  };
  bus::NodeOptions coarse;
  coarse.param("max_shift_m", 0.01).param("grid_step_m", 0.02);
  expect_error(coarse, "grid_step_m must be in (0, max_shift_m]");
  bus::NodeOptions range;
  range.param("min_range_m", 0.5).param("max_range_m", 0.2);
  expect_error(range, "min_range_m < max_range_m");
  bus::NodeOptions ratio;
  ratio.param("ambiguity_ratio", 1.5);
  expect_error(ratio, "ambiguity_ratio");
  bus::NodeOptions unknown;
  unknown.param("max_shift", 0.05);  // max_shift_m is
  expect_error(unknown, "max_shift");
}

TEST(LaserClusteringNodes, BadParametersStopTheNodeWithTheReason) {
  Harness h;
  bus::NodeOptions o;
  o.name = "finder";
  o.param("min_range_m", 0.5).param("max_range_m", 0.2);
  try {
    h.add("pedicel_finder", o);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("min_range_m < max_range_m"));
  }
  bus::NodeOptions u;
  u.name = "clusterer";
  u.param("groups_eps", 0.02);  // not a parameter (groups_eps_m is)
  EXPECT_THROW(h.add("line_clusterer", u), bus::ParamError);
  bus::NodeOptions r;
  r.name = "refl";
  r.param("eps_m", -1.0);
  EXPECT_THROW(h.add("reflectance_clusterer", r), bus::ParamError);
}

namespace {

// Figure 5.8 B-like scan whose metal reflectance follows a specular lobe over pitch.
lc::LineScan stick_scan(double pitch, double best_pitch, unsigned seed) {
  lc::test::SynthParams sp;
  sp.wall_z_m = 0.30;
  sp.wall_reflectance = 4.8;
  sp.noise_sd_m = 0.003;
  sp.seed = seed;
  const double lobe = 5.0 + 32.0 * std::exp(-0.5 * std::pow((pitch - best_pitch) / 0.07, 2));
  return lc::test::synth_scan({{0.0, 0.30 - 0.004 + 0.005, 0.005, lobe, 1}}, sp).scan;
}

}  // namespace

TEST(LaserClusteringNodes, ReflectanceClustererFindsTheMetal) {
  Harness h;
  bus::NodeOptions o;
  o.name = "refl";
  h.add("reflectance_clusterer", o);
  std::shared_ptr<const LineClusters> got;
  auto sub = h.io->create_subscription<LineClusters>("clusters", bus::QoS::keep_last(1),
                                                      [&](const std::shared_ptr<const LineClusters>& m) { got = m; });
  auto pub = h.io->create_publisher<LineScan>("scan");
  pub->publish(to_msg(stick_scan(0.0, 0.0, 3), 1.0));
  h.ex.spin_until_idle();
  ASSERT_TRUE(got);
  ASSERT_GE(got->brightest, 0);
  const auto& c = got->clusters[static_cast<std::size_t>(got->brightest)];
  EXPECT_NEAR(c.reflectance, 37.0, 4.0);
  EXPECT_NEAR(c.centroid_x_m, 0.0, 0.002);
}

TEST(LaserClusteringNodes, AlignmentSearchFindsThePitchOfAPitchSweep) {
  Harness h;
  bus::NodeOptions o;
  o.name = "align";
  o.param("pitch_joint", std::string("wrist_pitch"));
  o.param("surface_quantile", 0.99);  // the stick is about 3 % of the pixels
  h.add("alignment_search", o);
  auto& got = h.collect<AlignmentResult>("alignment", bus::QoS::keep_last(100));
  auto scans = h.io->create_publisher<LineScan>("scan");
  auto joints = h.io->create_publisher<JointState>("joint_states");
  const double deg = std::numbers::pi / 180.0, best = 3.3 * deg;
  // A scan without a pitch reading first: an explicit invalid result.
  scans->publish(to_msg(stick_scan(0.0, best, 1), 0.5));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0]->outcome, AlignmentResult::INVALID_INPUT);
  EXPECT_THAT(got[0]->reason, HasSubstr("no 'wrist_pitch' reading"));
  // The sweep: -10 .. +10 degrees in 2 degree steps, one scan per step.
  int k = 0;
  for (double p = -10 * deg; p <= 10.01 * deg; p += 2 * deg, ++k) {
    const double t = 1.0 + 0.1 * k;
    auto j = std::make_unique<JointState>();
    j->header.stamp = bus::Time::from_seconds(t).to_msg();
    j->name = {"elbow", "wrist_pitch"};
    j->position = {0.3, p};
    joints->publish(std::move(j));
    scans->publish(to_msg(stick_scan(p, best, static_cast<unsigned>(k + 10)), t + 0.01));
    h.ex.spin_until_idle();
  }
  const auto& last = *got.back();
  EXPECT_EQ(last.outcome, AlignmentResult::FOUND) << last.reason;
  EXPECT_EQ(last.num_samples, 11u);
  EXPECT_TRUE(last.refined);
  EXPECT_NEAR(last.best_pitch_rad, best, 0.5 * deg);
}

TEST(LaserClusteringNodes, MinReflectanceDropsDimReturns) {
  Harness h;
  bus::NodeOptions o;
  o.name = "clusterer";
  o.param("min_reflectance", 10.0);
  h.add("line_clusterer", o);
  auto& got = h.collect<LineClusters>("clusters", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto bright = to_msg(pedicel_scene(0.02).scan, 1.0);
  bright->reflectance.assign(bright->distance_m.size(), 20.0f);
  auto dim = to_msg(pedicel_scene(0.02).scan, 1.1);
  dim->reflectance.assign(dim->distance_m.size(), 5.0f);
  pub->publish(std::move(bright));
  pub->publish(std::move(dim));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_FALSE(got[0]->clusters.empty());
  EXPECT_TRUE(got[1]->clusters.empty()) << "every pixel is below min_reflectance";
  for (const int l : got[1]->labels) EXPECT_LT(l, 0);
}

TEST(LaserClusteringNodes, PitchSweepCommandsTheSweepThenTheFoundPitch) {
  Harness h;
  bus::NodeOptions o;
  o.name = "sweep";
  o.param("from_deg", -4.0).param("to_deg", 4.0).param("step_deg", 2.0).param("dwell_s", 0.1);
  h.add("pitch_sweep", o);
  std::vector<double> commands;
  std::vector<AlignmentResult> aligned;
  auto s1 = h.io->create_subscription<JointState>("joint_command", bus::QoS::keep_last(50),
                                                  [&](const JointState& m) { commands.push_back(m.position.at(0)); });
  auto s2 = h.io->create_subscription<AlignmentResult>("aligned", bus::QoS::keep_last(5),
                                                       [&](const AlignmentResult& m) { aligned.push_back(m); });
  auto pub = h.io->create_publisher<AlignmentResult>("alignment");
  h.ctx->clock().set_sim_time(bus::Time::from_seconds(10.0));
  h.ex.advance_to(bus::Time::from_seconds(10.45));
  ASSERT_EQ(commands.size(), 4u) << "one pitch per dwell";
  EXPECT_TRUE(aligned.empty());
  auto r = std::make_unique<AlignmentResult>();
  r->outcome = AlignmentResult::FOUND;
  r->best_pitch_rad = 0.01;
  pub->publish(std::move(r));
  h.ex.advance_to(bus::Time::from_seconds(11.0));
  ASSERT_EQ(commands.size(), 6u) << "5 pitches and the found one";
  EXPECT_NEAR(commands.front(), -4.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_NEAR(commands[4], 4.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(commands.back(), 0.01);
  ASSERT_EQ(aligned.size(), 1u);
  EXPECT_EQ(aligned[0].outcome, AlignmentResult::FOUND);
}

TEST(LaserClusteringNodes, PitchSweepWithoutAResultSaysWhyAndStays) {
  Harness h;
  bus::NodeOptions o;
  o.name = "sweep";
  o.param("from_deg", -2.0).param("to_deg", 2.0).param("step_deg", 2.0).param("dwell_s", 0.1);
  h.add("pitch_sweep", o);
  std::vector<double> commands;
  std::vector<AlignmentResult> aligned;
  auto s1 = h.io->create_subscription<JointState>("joint_command", bus::QoS::keep_last(50),
                                                  [&](const JointState& m) { commands.push_back(m.position.at(0)); });
  auto s2 = h.io->create_subscription<AlignmentResult>("aligned", bus::QoS::keep_last(5),
                                                       [&](const AlignmentResult& m) { aligned.push_back(m); });
  h.ctx->clock().set_sim_time(bus::Time::from_seconds(10.0));
  h.ex.advance_to(bus::Time::from_seconds(11.0));
  EXPECT_EQ(commands.size(), 3u) << "no move after the sweep";
  ASSERT_EQ(aligned.size(), 1u);
  EXPECT_EQ(aligned[0].outcome, AlignmentResult::INVALID_INPUT);
  EXPECT_THAT(aligned[0].reason, HasSubstr("no alignment result"));
}

TEST(LaserClusteringNodes, PitchSweepRejectsAnEmptyOrTooShortSweep) {
  Harness h;
  bus::NodeOptions backwards;
  backwards.name = "a";
  backwards.param("from_deg", 5.0).param("to_deg", -5.0);
  try {
    h.add("pitch_sweep", backwards);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("to_deg"));
  }
  bus::NodeOptions short_sweep;
  short_sweep.name = "b";
  short_sweep.param("from_deg", 0.0).param("to_deg", 1.0).param("step_deg", 0.6);
  try {
    h.add("pitch_sweep", short_sweep);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("at least 3"));
  }
}
