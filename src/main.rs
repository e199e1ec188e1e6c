use mujoco_rs::prelude::*;
fn main() {
    let m = MjModel::from_xml_string("<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>").unwrap();
    let mut d = MjData::new(&m);
    for _ in 0..100 { d.step(); }
    println!("z={}", d.qpos()[2]);
    let e = MjModel::from_xml_string("<mujoco><worldbody>\n<body><geom tpe='sphere'/></body></worldbody></mujoco>");
    println!("{:?}", e.err().map(|e| e.to_string()));
}
