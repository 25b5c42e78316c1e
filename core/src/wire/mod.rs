//! EtherCAT wire codec (see issue: foundation).
