// Dataset configurations with one bad value each, and the problem the check names (after
// "invalid dataset configuration: "). Included by models/tests/reliability.rs (check_config and
// generate) and tests/reliability.rs (`ace dataset --config`), so both levels refuse the same table.
// TOML has `nan` and `inf`; 1e30 is the finite absurd value.
const BAD_DATASET_CONFIGS: &[(&str, &str)] = &[
    // Zero, negative and absurd lengths and scales (0 made the speed scale infinite and the dataset NaN).
    (
        "[controller.scaling]\nhuman_leg_length = 0",
        "`controller.scaling.human_leg_length` = 0 is out of range: expected 0.1 to 10 (m)",
    ),
    (
        "[controller.scaling]\nhuman_leg_length = -0.9",
        "`controller.scaling.human_leg_length` = -0.9 is out of range: expected 0.1 to 10 (m)",
    ),
    (
        "[controller.scaling]\nhuman_height = 1e30",
        "`controller.scaling.human_height` = 1000000000000000000000000000000 is out of range: expected 0.1 to 10 (m)",
    ),
    (
        "[controller.scaling]\nspeed_scale = 0",
        "`controller.scaling.speed_scale` = 0 is out of range: expected 0.001 to 100 (character m/s per \
         human-equivalent m/s)",
    ),
    // Commands: inverted and absurd ranges, zero durations, probabilities out of 0..1.
    (
        "[controller.commands]\nforward = [5.0, -1.5]",
        "`controller.commands.forward` = [5, -1.5] is out of range: expected [low, high] with -20 ≤ low ≤ high ≤ 20 \
         (human-equivalent m/s)",
    ),
    (
        "[controller.commands]\nlateral = [-1e30, 1.0]",
        "`controller.commands.lateral` = [-1000000000000000000000000000000, 1] is out of range: expected [low, high] \
         with -20 ≤ low ≤ high ≤ 20 (human-equivalent m/s)",
    ),
    (
        "[controller.commands]\nslow = [1.8, -0.8]",
        "`controller.commands.slow` = [1.8, -0.8] is out of range: expected [low, high] with -20 ≤ low ≤ high ≤ 20 \
         (human-equivalent m/s)",
    ),
    (
        "[controller.commands]\nyaw_rate = [-1.0, inf]",
        "`controller.commands.yaw_rate` = [-1, inf] is out of range: expected [low, high] with -10 ≤ low ≤ high ≤ 10 \
         (rad/s)",
    ),
    (
        "[controller.commands]\nhold_seconds = [0.0, 0.0]",
        "`controller.commands.hold_seconds` = [0, 0] is out of range: expected [low, high] with 0.01 ≤ low ≤ high ≤ \
         3600 (s)",
    ),
    (
        "[controller.commands]\ntime_constant = 0",
        "`controller.commands.time_constant` = 0 is out of range: expected 0.001 to 60 (s)",
    ),
    (
        "[controller.commands]\np_stand = 1.5",
        "`controller.commands.p_stand` = 1.5 is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.commands]\np_turn = -0.1",
        "`controller.commands.p_turn` = -0.1 is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.commands]\np_lateral = nan",
        "`controller.commands.p_lateral` = NaN is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.commands]\np_slow = 2",
        "`controller.commands.p_slow` = 2 is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.commands]\np_stand = 0.6\np_turn = 0.6",
        "`controller.commands.p_stand` + `controller.commands.p_turn` = 0.6 + 0.6 is more than 1: they are \
         probabilities of one draw",
    ),
    // Posture.
    (
        "[controller.posture]\nheight = [0.1, -0.1]",
        "`controller.posture.height` = [0.1, -0.1] is out of range: expected [low, high] with -0.9 ≤ low ≤ high ≤ 1 \
         (fractions of the nominal height)",
    ),
    (
        "[controller.posture]\npitch = -0.1",
        "`controller.posture.pitch` = -0.1 is out of range: expected 0 to 1.5 (rad)",
    ),
    (
        "[controller.posture]\nroll = 1e30",
        "`controller.posture.roll` = 1000000000000000000000000000000 is out of range: expected 0 to 1.5 (rad)",
    ),
    (
        "[controller.posture]\nhold_seconds = [4.0, 1.0]",
        "`controller.posture.hold_seconds` = [4, 1] is out of range: expected [low, high] with 0.01 ≤ low ≤ high ≤ \
         3600 (s)",
    ),
    (
        "[controller.posture]\ntime_constant = -1",
        "`controller.posture.time_constant` = -1 is out of range: expected 0.001 to 60 (s)",
    ),
    // Legs.
    (
        "[controller.legs]\nmax_extension = 0",
        "`controller.legs.max_extension` = 0 is out of range: expected 0.05 to 1 (a fraction of the leg's reach)",
    ),
    (
        "[controller.legs]\nswing_height = 1e30",
        "`controller.legs.swing_height` = 1000000000000000000000000000000 is out of range: expected 0.01 to 1 (a \
         fraction of the leg length)",
    ),
    (
        "[controller.legs]\nmin_swing_frames = 0",
        "`controller.legs.min_swing_frames` = 0 is out of range: expected 1 to 1000 (frames)",
    ),
    (
        "[controller.legs]\nwalking_min_swing_frames = 4000000000",
        "`controller.legs.walking_min_swing_frames` = 4000000000 is out of range: expected 1 to 1000 (frames)",
    ),
    (
        "[controller.legs]\nbound_probability = 1.5",
        "`controller.legs.bound_probability` = 1.5 is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.legs]\nfrequency_time_constant = 0",
        "`controller.legs.frequency_time_constant` = 0 is out of range: expected 0.001 to 60 (s)",
    ),
    (
        "[controller.legs]\ncadence_limit = 0.5",
        "`controller.legs.cadence_limit` = 0.5 is out of range: expected 1 to 10 (times the law's stride frequency)",
    ),
    // Reaching.
    (
        "[controller.reach]\nstow_probability = -1",
        "`controller.reach.stow_probability` = -1 is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.reach]\nhold_seconds = [2.0, 0.5]",
        "`controller.reach.hold_seconds` = [2, 0.5] is out of range: expected [low, high] with 0.01 ≤ low ≤ high ≤ \
         3600 (s)",
    ),
    (
        "[controller.reach]\nspeed_fraction = 0",
        "`controller.reach.speed_fraction` = 0 is out of range: expected 0.001 to 1 (a fraction of the velocity \
         limit)",
    ),
    (
        "[controller.reach]\nmax_speed_fraction = 1e30",
        "`controller.reach.max_speed_fraction` = 1000000000000000000000000000000 is out of range: expected 0.001 to 1 \
         (a fraction of the velocity limit)",
    ),
    (
        "[controller.reach]\nspeed_fraction = 0.6\nmax_speed_fraction = 0.5",
        "`controller.reach.speed_fraction` = 0.6 is more than `controller.reach.max_speed_fraction` = 0.5: they are \
         the low and high ends of one range",
    ),
    (
        "[controller.reach]\nlocal_probability = 3",
        "`controller.reach.local_probability` = 3 is out of range: expected 0 to 1 (a probability)",
    ),
    (
        "[controller.reach]\nlocal_fraction = -0.15",
        "`controller.reach.local_fraction` = -0.15 is out of range: expected 0 to 1 (a fraction of each DoF's range)",
    ),
    (
        "[controller.reach]\nhome_reach = -0.25",
        "`controller.reach.home_reach` = -0.25 is out of range: expected 0 to 10 (a fraction of the arm's length)",
    ),
    (
        "[controller.reach]\ndefault_angular_speed = 0",
        "`controller.reach.default_angular_speed` = 0 is out of range: expected 0.01 to 100 (rad/s)",
    ),
    (
        "[controller.reach]\ndefault_linear_speed = -0.5",
        "`controller.reach.default_linear_speed` = -0.5 is out of range: expected 0.001 to 10 (m/s)",
    ),
    (
        "[controller.reach]\nmin_duration = 0",
        "`controller.reach.min_duration` = 0 is out of range: expected 0.01 to 60 (s)",
    ),
    (
        "[controller.reach]\nmargin = 1e30",
        "`controller.reach.margin` = 1000000000000000000000000000000 is out of range: expected 0 to 1 (m)",
    ),
    // The top-level fields.
    ("fps = 0", "`fps` = 0 is out of range: expected 1 to 1000"),
    (
        "episode_seconds = [24.0, 8.0]",
        "episode_seconds must be an increasing pair of positive numbers, not [24, 8]",
    ),
];
