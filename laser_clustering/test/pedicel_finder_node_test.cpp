// SPDX-License-Identifier: Apache-2.0
// The pedicel_finder node: detections, the vision's layout, the closed loop.

#include "node_rig.hpp"

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
