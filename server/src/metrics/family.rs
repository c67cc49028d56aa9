//! Building metric families for the scrape-time collector: counters, gauges and
//! histograms with labels, in the `prometheus` crate's model.

use prometheus::proto::{
    Bucket, Counter, Gauge, Histogram, LabelPair, Metric, MetricFamily, MetricType,
};

/// One family being filled.
pub struct Family {
    family: MetricFamily,
}

impl Family {
    /// A family named `name` of type `kind`.
    pub fn new(name: &str, help: &str, kind: MetricType) -> Family {
        let mut family = MetricFamily::default();
        family.set_name(name.to_owned());
        family.set_help(help.to_owned());
        family.set_field_type(kind);
        Family { family }
    }

    fn metric(labels: &[(&str, &str)]) -> Metric {
        let mut metric = Metric::default();
        metric.set_label(
            labels
                .iter()
                .map(|(name, value)| {
                    let mut pair = LabelPair::default();
                    pair.set_name((*name).to_owned());
                    pair.set_value((*value).to_owned());
                    pair
                })
                .collect(),
        );
        metric
    }

    /// Adds a counter sample.
    pub fn counter(mut self, labels: &[(&str, &str)], value: f64) -> Family {
        let mut metric = Family::metric(labels);
        let mut counter = Counter::default();
        counter.set_value(value);
        metric.set_counter(counter);
        self.family.mut_metric().push(metric);
        self
    }

    /// Adds a gauge sample.
    pub fn gauge(mut self, labels: &[(&str, &str)], value: f64) -> Family {
        let mut metric = Family::metric(labels);
        let mut gauge = Gauge::default();
        gauge.set_value(value);
        metric.set_gauge(gauge);
        self.family.mut_metric().push(metric);
        self
    }

    /// Adds a histogram sample: cumulative counts per upper bound (seconds), total count
    /// and sum.
    pub fn histogram(
        mut self,
        labels: &[(&str, &str)],
        buckets: &[(f64, u64)],
        count: u64,
        sum: f64,
    ) -> Family {
        let mut metric = Family::metric(labels);
        let mut histogram = Histogram::default();
        histogram.set_sample_count(count);
        histogram.set_sample_sum(sum);
        histogram.set_bucket(
            buckets
                .iter()
                .map(|&(bound, cumulative)| {
                    let mut bucket = Bucket::default();
                    bucket.set_upper_bound(bound);
                    bucket.set_cumulative_count(cumulative);
                    bucket
                })
                .collect(),
        );
        metric.set_histogram(histogram);
        self.family.mut_metric().push(metric);
        self
    }

    /// The family, or nothing when it has no sample (the text format wants none empty).
    pub fn done(self) -> Option<MetricFamily> {
        (!self.family.get_metric().is_empty()).then_some(self.family)
    }
}
