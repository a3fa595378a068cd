// SPDX-License-Identifier: Apache-2.0
// The harvesting pipeline on the bus, as launch/tomato_harvest.launch.yaml
// wires it: truss_camera -> tomato_detector -> pick_verifier -> sim_gripper
// (scan) -> laser_clustering pedicel_finder -> pick_verifier -> sim_gripper
// (cut) -> pick_verifier ... -> harvest_score, stepped by the deterministic
// executor on sim time (no sleeps).
#include <cmath>
#include <cstring>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>
#include <tinyline/msg/tinyline_msgs/harvest_score.hpp>

#include <laser_clustering/nodes/register.hpp>
#include <sim/scenes/truss.hpp>

#include "tomato_reasoning/nodes/nodes.hpp"
#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/nodes/register.hpp"
#include "tomato_reasoning/sim/register.hpp"

namespace bus = tinyline::bus;
namespace tr = tinyline::tomato_reasoning;
using tinyline::geometry_msgs::msg::PoseStamped;
using tinyline::sensor_msgs::msg::PointCloud2;
using tinyline::tinyline_msgs::msg::CutOutcome;
using tinyline::tinyline_msgs::msg::HarvestPick;
using tinyline::tinyline_msgs::msg::HarvestScore;
using tinyline::tinyline_msgs::msg::HarvestSummary;
using tinyline::tinyline_msgs::msg::PickVerification;
using tinyline::tinyline_msgs::msg::TomatoEstimates;
using tinyline::visualization_msgs::msg::MarkerArray;

namespace {

// The tomato_reasoning and laser_clustering nodes, and the simulated camera
// and hand laser, on stepped sim time
// (bus/testing.hpp).
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&tr::register_nodes, &tinyline::laser_clustering::register_nodes, &tr::register_sim_nodes}) {}
};

}  // namespace

TEST(TomatoNodes, AllAreRegistered) {
  bus::NodeRegistry r;
  tr::register_nodes(r);
  tr::register_sim_nodes(r);  // the demo's simulated camera and hand laser
  for (const char* t : {"tomato_detector", "pick_verifier", "truss_camera", "sim_gripper", "harvest_score"})
    EXPECT_NE(r.find("tomato_reasoning", t), nullptr) << t;
}

TEST(TomatoNodes, CloudConversionRoundTripsAndRejectsShortData) {
  tr::ColorCloud c;
  c.width = 2;
  c.height = 2;
  c.xyz = {{0, 0, 1}, {NAN, NAN, NAN}, {0.1f, 0.2f, 0.3f}, {1, 2, 3}};
  c.rgb = {{200, 10, 20}, {0, 0, 0}, {1, 2, 3}, {255, 255, 255}};
  PointCloud2 m;
  tr::nodes::to_msg(c, m);
  EXPECT_FALSE(m.is_dense);
  tr::ColorCloud back;
  ASSERT_EQ(tr::nodes::to_core(m, back), "");
  EXPECT_EQ(back.width, 2);
  EXPECT_EQ(back.height, 2);
  EXPECT_EQ(back.rgb, c.rgb);
  EXPECT_EQ(back.xyz[2], c.xyz[2]);
  EXPECT_FALSE(back.finite(1));
  m.data.resize(m.data.size() - 1);
  EXPECT_THAT(tr::nodes::to_core(m, back), ::testing::HasSubstr("too few"));
  m.fields.pop_back();
  EXPECT_THAT(tr::nodes::to_core(m, back), ::testing::HasSubstr("rgb"));
}

TEST(TomatoNodes, DetectorSaysWhyABadCloudHasNoTomatoes) {
  Harness h;
  bus::NodeOptions o;
  o.name = "detector";
  h.add("tomato_reasoning", "tomato_detector", o);
  auto& got = h.collect<TomatoEstimates>("tomatoes", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<PointCloud2>("cloud");
  h.ex.spin_until_idle();
  pub->publish(std::make_unique<PointCloud2>());  // no fields
  tr::ColorCloud green;
  for (int i = 0; i < 500; ++i) green.push_back({0.01f * float(i % 20), 0.01f * float(i / 20), 0.5f}, {20, 200, 30});
  auto m = std::make_unique<PointCloud2>();
  tr::nodes::to_msg(green, *m);
  pub->publish(std::move(m));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0]->stage, "input");
  EXPECT_TRUE(got[0]->tomatoes.empty());
  EXPECT_EQ(got[1]->stage, "hsi");
  EXPECT_EQ(got[1]->red_points, 0u);
}

namespace {

// The demo's graph (launch/tomato_harvest.launch.yaml) on truss (class, seed).
void add_harvest(Harness& h, const std::string& truss_class, std::int64_t seed) {
  bus::NodeOptions cam, det, ver, hand, finder, score;
  cam.name = "camera";
  // Two hand-camera views, as the launch file (and the thesis's robot).
  cam.param("truss_class", truss_class).param("seed", seed).param("rate_hz", 1.0).param("views", std::int64_t(2));
  cam.remap("cloud", "/camera/cloud").remap("cloud2", "/camera2/cloud").remap("cloud2_pose", "/camera2/pose");
  cam.remap("truth", "/camera/truth").remap("cut_outcome", "/hand/cut_outcome");
  det.name = "detector";
  det.param("views", std::int64_t(2)).remap("cloud", "/camera/cloud").remap("cloud2", "/camera2/cloud");
  det.remap("cloud2_pose", "/camera2/pose").remap("tomatoes", "/tomatoes").remap("markers", "/tomatoes/markers");
  ver.name = "verifier";
  ver.remap("tomatoes", "/tomatoes")
      .remap("pick_pose", "/hand/pick_pose")
      .remap("expected_pedicel", "/hand/expected_pedicel");
  ver.remap("pedicel", "/hand/pedicel")
      .remap("verification", "/verification")
      .remap("markers", "/verification/markers");
  ver.remap("cut", "/hand/cut").remap("cut_outcome", "/hand/cut_outcome").remap("summary", "/harvest/summary");
  hand.name = "hand";
  hand.param("truss_class", truss_class).param("seed", seed);
  hand.remap("pick_pose", "/hand/pick_pose").remap("scan", "/hand/scan").remap("cut", "/hand/cut");
  hand.remap("cut_outcome", "/hand/cut_outcome");
  finder.name = "pedicel_finder";
  finder.param("scissor_centre_z_m", 0.12);
  finder.remap("scan", "/hand/scan")
      .remap("expected_pedicel", "/hand/expected_pedicel")
      .remap("pedicel", "/hand/pedicel");
  score.name = "harvest_score";
  score.param("truss_class", truss_class).param("seed", seed);
  score.remap("summary", "/harvest/summary").remap("cut_outcome", "/hand/cut_outcome").remap("score", "/harvest/score");
  h.add("tomato_reasoning", "truss_camera", cam);
  h.add("tomato_reasoning", "tomato_detector", det);
  h.add("tomato_reasoning", "pick_verifier", ver);
  h.add("tomato_reasoning", "sim_gripper", hand);
  h.add("laser_clustering", "pedicel_finder", finder);
  h.add("tomato_reasoning", "harvest_score", score);
}

}  // namespace

TEST(TomatoNodes, HarvestPipelineFindsOrdersVerifiesAndCutsEveryTomato) {
  Harness h;
  add_harvest(h, "A", 4);  // two tomatoes, each cut on its own pick (seed 3's single one jams on the peduncle)
  auto& tomatoes = h.collect<TomatoEstimates>("/tomatoes", bus::QoS::keep_last(10));
  auto& verified = h.collect<PickVerification>("/verification", bus::QoS::keep_last(10));
  auto& markers = h.collect<MarkerArray>("/tomatoes/markers", bus::QoS::keep_last(10));
  auto& cuts = h.collect<CutOutcome>("/hand/cut_outcome", bus::QoS::keep_last(10));
  auto& summaries = h.collect<HarvestSummary>("/harvest/summary", bus::QoS::keep_last(10));
  auto& scores = h.collect<HarvestScore>("/harvest/score", bus::QoS::keep_last(10));
  h.ex.advance_to(bus::Time::from_seconds(100.0));  // starts the nodes; timers count from here
  EXPECT_TRUE(tomatoes.empty());                    // the camera's first frame comes one period after start
  h.ex.advance_to(bus::Time::from_seconds(101.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(tomatoes.size(), 1u);
  const auto& t = *tomatoes.front();
  ASSERT_FALSE(t.tomatoes.empty()) << t.stage << ": " << t.reason;
  EXPECT_EQ(t.header.frame_id, "camera");
  EXPECT_EQ(t.pick_order.size(), t.tomatoes.size());
  ASSERT_GE(verified.size(), t.tomatoes.size());
  EXPECT_EQ(verified.front()->pick_rank, 0);
  EXPECT_EQ(verified.front()->tomato, t.pick_order[0]);
  EXPECT_EQ(verified.front()->attempt, 1);
  ASSERT_EQ(summaries.size(), 1u);
  const HarvestSummary& s = *summaries.front();
  EXPECT_EQ(s.detected, t.tomatoes.size());
  ASSERT_EQ(s.picks.size(), t.tomatoes.size());
  for (std::size_t k = 0; k < s.picks.size(); ++k) {
    EXPECT_EQ(s.picks[k].pick_rank, int(k));
    EXPECT_EQ(s.picks[k].tomato, t.pick_order[k]);
    EXPECT_EQ(s.picks[k].outcome, HarvestPick::PICKED) << s.picks[k].detail;
  }
  ASSERT_EQ(cuts.size(), t.tomatoes.size());
  for (const auto& c : cuts) {
    EXPECT_EQ(c->result, CutOutcome::CUT_TARGET) << c->object;
    EXPECT_EQ(c->fallen, std::vector<std::int32_t>{c->target_truth});
  }
  ASSERT_EQ(scores.size(), 1u);
  const HarvestScore& sc = *scores.front();
  EXPECT_TRUE(sc.accounted) << sc.reason;
  EXPECT_EQ(sc.trials, t.tomatoes.size());
  EXPECT_EQ(sc.detected, sc.trials);
  EXPECT_EQ(sc.picked_first + sc.picked_second, sc.trials);
  EXPECT_EQ(sc.picked_first + sc.picked_second + sc.human + sc.cut_failures, sc.trials);
  ASSERT_FALSE(markers.empty());
  EXPECT_GE(markers.front()->markers.size(), 1 + 4 * t.tomatoes.size());
  EXPECT_TRUE(h.log->contains(bus::LogLevel::Info, "harvest summary"));
  EXPECT_TRUE(h.log->contains(bus::LogLevel::Info, "every one of"));
  // The picked fruit fell out of the camera's world: the next frame has no tomato.
  h.ex.advance_to(bus::Time::from_seconds(102.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(tomatoes.size(), 2u);
  EXPECT_TRUE(tomatoes.back()->tomatoes.empty()) << tomatoes.back()->tomatoes.size() << " tomatoes left";
}

// The pick_verifier alone, its peers played by the test: it waits for the
// gripper's report (it neither skips the pick nor invents an outcome), ignores
// a report for another pick, re-scans once after blades that closed on
// nothing, and ends the harvest with a jam as a cut failure at attempt 2.
TEST(TomatoNodes, PickVerifierWaitsForTheGrippersReportAndRescansOnce) {
  using tinyline::tinyline_msgs::msg::CutCommand;
  using tinyline::tinyline_msgs::msg::PedicelDetection;
  Harness h;
  bus::NodeOptions o;
  o.name = "verifier";
  h.add("tomato_reasoning", "pick_verifier", o);
  auto& poses = h.collect<PoseStamped>("pick_pose", bus::QoS::keep_last(10));
  auto& commands = h.collect<CutCommand>("cut", bus::QoS::keep_last(10));
  auto& summaries = h.collect<HarvestSummary>("summary", bus::QoS::keep_last(10));
  auto tomatoes = h.io->create_publisher<TomatoEstimates>("tomatoes");
  auto pedicel = h.io->create_publisher<PedicelDetection>("pedicel");
  auto outcome = h.io->create_publisher<CutOutcome>("cut_outcome");
  h.ex.spin_until_idle();
  auto t = std::make_unique<TomatoEstimates>();
  t->header.frame_id = "camera";
  tinyline::tinyline_msgs::msg::TomatoEstimate e;
  e.centre.z = 0.45;
  e.radius_m = 0.03;
  e.cut_point.y = -0.04;
  e.cut_point.z = 0.45;
  e.cut_direction.y = -1.0;  // up in the camera's optical frame
  t->tomatoes.push_back(e);
  t->pick_order = {0};
  tomatoes->publish(std::move(t));
  h.ex.spin_until_idle();
  ASSERT_EQ(poses.size(), 1u);
  auto answer = [&](std::uint8_t what) {
    auto d = std::make_unique<PedicelDetection>();
    d->outcome = what;
    d->position.z = 0.12;
    pedicel->publish(std::move(d));
    h.ex.spin_until_idle();
  };
  auto report = [&](int rank, std::uint8_t result) {
    auto c = std::make_unique<CutOutcome>();
    c->pick_rank = rank;
    c->result = result;
    outcome->publish(std::move(c));
    h.ex.spin_until_idle();
  };
  answer(PedicelDetection::CUT_HERE);
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(commands[0]->attempt, 1);
  EXPECT_EQ(commands[0]->tomato, 0);
  EXPECT_DOUBLE_EQ(commands[0]->throat_z_m, 0.12);
  report(5, CutOutcome::CUT_TARGET);  // not this pick's
  EXPECT_TRUE(summaries.empty());
  report(0, CutOutcome::CLOSED_ON_NOTHING);
  ASSERT_EQ(poses.size(), 2u);  // the re-scan, from where the blades closed
  EXPECT_NEAR(poses[1]->pose.position.y, poses[0]->pose.position.y, 1e-12);
  EXPECT_TRUE(summaries.empty());
  answer(PedicelDetection::CUT_HERE);
  ASSERT_EQ(commands.size(), 2u);
  EXPECT_EQ(commands[1]->attempt, 2);
  report(0, CutOutcome::JAMMED);
  ASSERT_EQ(summaries.size(), 1u);
  ASSERT_EQ(summaries[0]->picks.size(), 1u);
  EXPECT_EQ(summaries[0]->picks[0].outcome, HarvestPick::CUT_FAILURE);
  EXPECT_EQ(summaries[0]->picks[0].attempts, 2);
  EXPECT_EQ(summaries[0]->picks[0].detail, "1: cut_here -> closed_on_nothing; 2: cut_here -> jammed");
}

// harvest_score against the truss's truth: Table 4.2's columns from a summary
// and the gripper's reports, in either order; a detected tomato without a
// pick is said, not scored as fine.
TEST(TomatoNodes, HarvestScoreCountsTable42AgainstTheTruth) {
  using tinyline::tinyline_msgs::msg::CutOutcome;
  Harness h;
  bus::NodeOptions o;
  o.name = "score";
  o.param("truss_class", std::string("A")).param("seed", std::int64_t(4));
  h.add("tomato_reasoning", "harvest_score", o);
  auto& scores = h.collect<HarvestScore>("score", bus::QoS::keep_last(10));
  auto summary = h.io->create_publisher<HarvestSummary>("summary");
  auto outcome = h.io->create_publisher<CutOutcome>("cut_outcome");
  h.ex.advance_to(bus::Time::from_seconds(1.0));  // starts the node (it builds the truss)
  h.ex.spin_until_idle();
  tinyline::sim::TrussParams tp;
  tp.complexity = tinyline::sim::TrussClass::kA;
  tp.seed = 4;
  const auto truss = tinyline::sim::make_truss(tp);
  ASSERT_EQ(truss.tomatoes.size(), 2u);
  auto pick = [&](int rank, int truth, std::uint8_t what, std::uint8_t attempts) {
    HarvestPick p;
    p.tomato = rank;
    p.pick_rank = rank;
    const Eigen::Vector3d c = truss.T_world_camera.inverse() * truss.tomatoes[std::size_t(truth)].centre_m;
    p.centre.x = c.x(), p.centre.y = c.y(), p.centre.z = c.z();
    p.radius_m = truss.tomatoes[std::size_t(truth)].radius_m;
    p.outcome = what;
    p.attempts = attempts;
    return p;
  };
  auto report = [&](int rank, int truth, std::uint8_t result, std::uint8_t attempt) {
    auto c = std::make_unique<CutOutcome>();
    c->pick_rank = rank;
    c->attempt = attempt;
    c->result = result;
    c->target_truth = truth;
    if (result == CutOutcome::CUT_TARGET) c->fallen = {truth};
    outcome->publish(std::move(c));
    h.ex.spin_until_idle();
  };
  auto s = std::make_unique<HarvestSummary>();
  s->detected = 2;
  s->picks = {pick(0, 1, HarvestPick::PICKED, 2), pick(1, 0, HarvestPick::CUT_FAILURE, 1)};
  report(0, 1, CutOutcome::CLOSED_ON_NOTHING, 1);  // attempt 1 of pick 0
  summary->publish(std::move(s));
  h.ex.spin_until_idle();
  EXPECT_TRUE(scores.empty());  // pick 0's second closing and pick 1's are not in yet
  report(0, 1, CutOutcome::CUT_TARGET, 2);
  EXPECT_TRUE(scores.empty());
  report(1, 0, CutOutcome::JAMMED, 1);
  ASSERT_EQ(scores.size(), 1u);
  const HarvestScore& sc = *scores[0];
  EXPECT_TRUE(sc.accounted) << sc.reason;
  EXPECT_EQ(sc.trials, 2u);
  EXPECT_EQ(sc.detected, 2u);
  EXPECT_EQ(sc.picked_first, 0u);
  EXPECT_EQ(sc.picked_second, 1u);
  EXPECT_EQ(sc.cut_failures, 1u);
  EXPECT_EQ(sc.human, 0u);
  EXPECT_EQ(sc.truss_class, "A");

  // Another run: one of two detected tomatoes has no pick, and the other is
  // not where any truss tomato is (not detected, left for a human).
  Harness h2;
  h2.add("tomato_reasoning", "harvest_score", o);
  auto& scores2 = h2.collect<HarvestScore>("score", bus::QoS::keep_last(10));
  auto summary2 = h2.io->create_publisher<HarvestSummary>("summary");
  h2.ex.advance_to(bus::Time::from_seconds(1.0));
  h2.ex.spin_until_idle();
  auto bad = std::make_unique<HarvestSummary>();
  bad->detected = 2;
  HarvestPick nowhere = pick(0, 0, HarvestPick::LEFT_FOR_HUMAN, 1);
  nowhere.centre.z += 0.5;
  bad->picks = {nowhere};
  summary2->publish(std::move(bad));
  h2.ex.spin_until_idle();
  ASSERT_EQ(scores2.size(), 1u);
  EXPECT_FALSE(scores2[0]->accounted);
  EXPECT_EQ(scores2[0]->reason, "tomato 1 has no pick");
  EXPECT_EQ(scores2[0]->detected, 0u);
  EXPECT_EQ(scores2[0]->human, 2u);
  EXPECT_TRUE(h2.log->contains(bus::LogLevel::Error, "unaccounted"));
}

// The thesis's robot took two hand-camera views (4.5): the camera publishes
// the second view and its pose, the detector with views: 2 fuses them, and on
// dense class C trusses it finds fruit the one-view detector on the same
// first view cannot see.
TEST(TomatoNodes, TwoViewDetectorFusesTheSecondViewAtItsPose) {
  int truth = 0, found_one = 0, found_two = 0;
  for (std::int64_t seed : {1002, 1004}) {  // the core test's trusses (Pipeline.TwoViewsRecoverFruitOneViewCannotSee)
    Harness h;
    bus::NodeOptions cam, one, two;
    cam.name = "camera";
    cam.param("truss_class", std::string("C"))
        .param("seed", seed)
        .param("rate_hz", 1.0)
        .param("views", std::int64_t(2))
        .param("physics", std::string("pendulum"));  // the world the core test's trusses come from
    one.name = "one_view";
    one.remap("tomatoes", "/one/tomatoes");
    two.name = "two_views";
    two.param("views", std::int64_t(2)).remap("tomatoes", "/two/tomatoes");
    h.add("tomato_reasoning", "truss_camera", cam);
    h.add("tomato_reasoning", "tomato_detector", one);
    h.add("tomato_reasoning", "tomato_detector", two);
    std::vector<std::shared_ptr<const TomatoEstimates>> got1, got2;
    auto s1 = h.io->create_subscription<TomatoEstimates>(
        "/one/tomatoes", bus::QoS::keep_last(4),
        [&](const std::shared_ptr<const TomatoEstimates>& m) { got1.push_back(m); });
    auto s2 = h.io->create_subscription<TomatoEstimates>(
        "/two/tomatoes", bus::QoS::keep_last(4),
        [&](const std::shared_ptr<const TomatoEstimates>& m) { got2.push_back(m); });
    h.ex.advance_to(bus::Time::from_seconds(100.0));  // starts the nodes; the first frame one period later
    h.ex.advance_to(bus::Time::from_seconds(101.0));
    h.ex.spin_until_idle();
    ASSERT_EQ(got1.size(), 1u);
    ASSERT_EQ(got2.size(), 1u);
    EXPECT_EQ(got2.front()->header.frame_id, "camera");  // results in the first view's frame
    tr::eval::ScenarioOptions so;
    so.views = 2;
    const auto sc = tr::eval::make_scenario(tinyline::sim::TrussClass::kC, std::uint64_t(seed), so);
    auto detected = [&](const TomatoEstimates& m) {
      int n = 0;
      for (const auto& t : sc.truth) {
        bool hit = false;
        for (const auto& e : m.tomatoes)
          hit |= (Eigen::Vector3d(e.centre.x, e.centre.y, e.centre.z) - t.centre_m).norm() <= 0.01;
        n += hit;
      }
      return n;
    };
    truth += int(sc.truth.size());
    found_one += detected(*got1.front());
    found_two += detected(*got2.front());
  }
  EXPECT_GT(found_two, found_one);
  EXPECT_GE(found_two, truth - 1);
}

TEST(TomatoNodes, TwoViewDetectorWaitsForBothViewsAndRejectsABadPose) {
  Harness h;
  bus::NodeOptions o;
  o.name = "detector";
  o.param("views", std::int64_t(2));
  h.add("tomato_reasoning", "tomato_detector", o);
  auto& got = h.collect<TomatoEstimates>("tomatoes", bus::QoS::keep_last(10));
  auto cloud = h.io->create_publisher<PointCloud2>("cloud");
  auto cloud2 = h.io->create_publisher<PointCloud2>("cloud2");
  auto pose2 = h.io->create_publisher<PoseStamped>("cloud2_pose");
  h.ex.spin_until_idle();
  tr::ColorCloud red;
  for (int i = 0; i < 400; ++i) red.push_back({0.002f * float(i % 20), 0.002f * float(i / 20), 0.5f}, {200, 40, 30});
  auto send_cloud = [&](auto& pub, int sec) {
    auto m = std::make_unique<PointCloud2>();
    tr::nodes::to_msg(red, *m);
    m->header.stamp.sec = sec;
    pub->publish(std::move(m));
  };
  auto send_pose = [&](int sec, double qw) {
    auto p = std::make_unique<PoseStamped>();
    p->header.stamp.sec = sec;
    p->pose.orientation.w = qw;
    pose2->publish(std::move(p));
  };
  send_cloud(cloud, 1);
  send_cloud(cloud2, 1);
  h.ex.spin_until_idle();
  EXPECT_TRUE(got.empty());  // no pose for the second view yet
  send_pose(2, 1.0);         // another stamp: still waiting
  h.ex.spin_until_idle();
  EXPECT_TRUE(got.empty());
  send_pose(1, 0.5);  // not a unit quaternion
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0]->stage, "input");
  EXPECT_NE(got[0]->reason.find("cloud2_pose"), std::string::npos) << got[0]->reason;
  send_cloud(cloud2, 3);
  send_pose(3, 1.0);
  auto broken = std::make_unique<PointCloud2>();  // a reference view without fields: said at once
  broken->header.stamp.sec = 3;
  cloud->publish(std::move(broken));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1]->stage, "input");
  EXPECT_NE(got[1]->reason.find("view 0"), std::string::npos) << got[1]->reason;
  send_cloud(cloud, 4);
  send_cloud(cloud2, 4);
  send_pose(4, 1.0);  // both views of one stamp at a good pose: a detection runs
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 3u);
  EXPECT_NE(got[2]->stage, "input") << got[2]->reason;
}
