// SPDX-License-Identifier: Apache-2.0
// The tomato_registration node.

#include "node_rig.hpp"

namespace {

// The tomato look (tomato_registration_test's truss): four tomatoes, each
// its own size and depth, cut 1 cm below their centres; the vision sees them
// all moved by -offset, each off by its own few millimetres.
const std::vector<lc::test::Disc> kTruss{{-0.11, 0.23, 0.028, 6.0, 1},
                                         {-0.04, 0.21, 0.033, 6.0, 2},
                                         {0.035, 0.24, 0.026, 6.0, 3},
                                         {0.10, 0.22, 0.031, 6.0, 4}};

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
  EXPECT_EQ(r.ok, core.status.ok());
  EXPECT_EQ(r.reason, core.status.ok() ? core.note : core.status.message);
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
  EXPECT_EQ(look.got[2]->ok, bounded.status.ok());
  EXPECT_EQ(look.got[2]->reason, bounded.status.ok() ? bounded.note : bounded.status.message);
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
